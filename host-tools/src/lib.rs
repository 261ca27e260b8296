//! host tools
