//! Helper threads of a calculation that uses every core (the swarm's team, the
//! cross-validation's folds): started off the calling thread's CPU, at once.
//!
//! A new thread is queued on its parent's CPU. While the parent computes, the scheduler runs the
//! new thread there only when the parent's time slice ends or the load is balanced, milliseconds
//! later; until then the helper does not work and, once it runs, it shares the CPU with the
//! parent (waits of milliseconds measured with `perf sched timehist`: docs/JOURNAL.md, "Speed to
//! the limit"). [`spawn`] therefore moves the helper off the parent's CPU as its first step and yields the
//! parent's CPU once, so that a helper queued there runs (and moves) at once.

use std::thread::{Scope, ScopedJoinHandle};

/// Starts `work` on a helper thread named `name` in `scope`, kept off the calling thread's CPU
/// where the system allows it (see the module docs); `None` when the system cannot start a
/// thread (the caller then does the work with one thread fewer).
pub(crate) fn spawn<'scope, T: Send + 'scope>(
    scope: &'scope Scope<'scope, '_>,
    name: &str,
    work: impl FnOnce() -> T + Send + 'scope,
) -> Option<ScopedJoinHandle<'scope, T>> {
    spawn_off(scope, name, current_cpu(), work)
}

/// [`spawn`] kept off `caller_cpu`.
fn spawn_off<'scope, T: Send + 'scope>(
    scope: &'scope Scope<'scope, '_>,
    name: &str,
    caller_cpu: Option<usize>,
    work: impl FnOnce() -> T + Send + 'scope,
) -> Option<ScopedJoinHandle<'scope, T>> {
    let handle = std::thread::Builder::new()
        .name(name.into())
        .spawn_scoped(scope, move || {
            keep_off(caller_cpu);
            work()
        })
        .ok()?;
    // A helper queued on this CPU runs now and moves itself to another (a few microseconds);
    // one queued elsewhere leaves nothing to yield to and this returns at once.
    std::thread::yield_now();
    Some(handle)
}

/// The CPU the calling thread runs on, where the system says.
fn current_cpu() -> Option<usize> {
    #[cfg(target_os = "linux")]
    {
        nix::sched::sched_getcpu().ok()
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// Keeps the calling helper off `cpu` (its parent's CPU when it was started), where the system
/// allows it; nothing happens when `cpu` is the only one allowed, or unknown.
///
/// Measured on this 2-vCPU machine with a scratch program that runs the paper's swarm on a team
/// once in a fresh process (four runs each, alternating): 19.9-26.0 ms without this, 18.9-21.7
/// ms with it.
fn keep_off(cpu: Option<usize>) {
    #[cfg(target_os = "linux")]
    if let Some(cpu) = cpu {
        use nix::sched::{sched_getaffinity, sched_setaffinity};
        let this_thread = nix::unistd::Pid::from_raw(0);
        if let Ok(mut allowed) = sched_getaffinity(this_thread)
            && allowed.is_set(cpu).unwrap_or(false)
            && allowed.unset(cpu).is_ok()
        {
            // Fails (and changes nothing) when no other CPU is allowed.
            let _ = sched_setaffinity(this_thread, &allowed);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = cpu;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A helper works and gives its result back; on Linux, when two or more CPUs are allowed, it
    /// is kept off the CPU it was told (the first allowed one): that CPU is not in its affinity
    /// mask and it does not run there.
    #[test]
    fn a_helper_works_off_the_callers_cpu() {
        #[cfg(target_os = "linux")]
        let allowed = nix::sched::sched_getaffinity(nix::unistd::Pid::from_raw(0))
            .expect("the affinity mask is readable");
        #[cfg(target_os = "linux")]
        let cpus: Vec<usize> = (0..nix::sched::CpuSet::count())
            .filter(|c| allowed.is_set(*c).unwrap_or(false))
            .collect();
        #[cfg(not(target_os = "linux"))]
        let cpus: Vec<usize> = Vec::new();
        let avoided = cpus.first().copied();
        let (result, helper_cpu, helper_allows_avoided) = std::thread::scope(|scope| {
            let handle = spawn_off(scope, "calib-test-helper", avoided, || {
                #[cfg(target_os = "linux")]
                let allows = avoided.map(|c| {
                    nix::sched::sched_getaffinity(nix::unistd::Pid::from_raw(0))
                        .map(|mask| mask.is_set(c).unwrap_or(true))
                        .unwrap_or(true)
                });
                #[cfg(not(target_os = "linux"))]
                let allows: Option<bool> = None;
                (6 * 7, current_cpu(), allows)
            })
            .expect("a thread starts");
            handle.join().expect("the helper does not panic")
        });
        assert_eq!(result, 42);
        if cpus.len() >= 2 {
            assert_eq!(helper_allows_avoided, Some(false), "CPUs {cpus:?}");
            assert_ne!(helper_cpu, avoided, "the helper ran on the avoided CPU");
        }
    }
}
