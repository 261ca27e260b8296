//! What a model and a dataset say beyond the fit: the accuracy on held-out poses as a certificate
//! states it, where in the workspace the error remains and the caveats that limit it, the uncertainty of a prediction propagated from the parameters' covariance and the budget of the accuracy statement, the
//! identifiability of the parameters, the kinds of measurement the calibration is generic over
//! (poses, touches in sockets), the
//! evaluation of a model on new poses, the comparison against a known truth, and the verification
//! of the core's calibration against the independent float64 reference.

pub mod accuracy;
pub mod budget;
pub mod caveats;
pub mod consistency;
pub mod consistency_prediction;
pub mod evaluation;
pub mod identifiability;
pub mod kind;
pub mod reference;
pub mod truth;
pub mod uncertainty;
pub mod workspace;
