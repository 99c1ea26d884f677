//! The stepping thread at real-time priority (docs/design.md §10): `SCHED_FIFO` for the thread that
//! keeps the clock, and the process's memory locked so that a page fault cannot stall a
//! step. Both as far as the OS allows; what it refused, and why, is said rather than fatal:
//! a session on a laptop without the privilege still runs, with the warning in the events
//! and the summary's `live.realtime`.
//!
//! The clock thread is raised: it sleeps between steps (the loop in [`super::run`] never
//! spins), so a `SCHED_FIFO` thread cannot starve the simulator or the console beside it
//! for longer than one step's work. Threads it starts while raised (the S-MPC's second QP)
//! inherit its policy, as the step's own work should. The thread that takes frames to the
//! recording, Foxglove and the console is started before and raised to
//! [`SINKS_PRIORITY`], below the clock.

use hexcue_core::summary::RealtimeSummary;

/// The `SCHED_FIFO` priority of the stepping thread unless told otherwise: above every
/// normal thread, level with the kernel's threaded interrupt handlers (50), below its
/// watchdog and migration threads (99).
pub const DEFAULT_PRIORITY: i32 = 50;

/// The sink thread's `SCHED_FIFO` priority when the stepping thread is raised: the lowest,
/// below every other real-time thread and above every normal one.
pub const SINKS_PRIORITY: i32 = 1;

/// Raises the calling thread to `SCHED_FIFO` at `priority` for the rest of its life, without
/// touching memory locking; the reason when refused.
pub fn raise_current_thread(priority: i32) -> Result<(), String> {
    #[cfg(target_os = "linux")]
    {
        linux::set_fifo(priority).map(|_| ())
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = priority;
        Err("not supported on this OS (Linux only)".to_string())
    }
}

/// What the stepping thread asked of the OS, and what it got. Dropping it puts the thread
/// back on the policy it had and unlocks the memory it locked.
pub struct RealtimeGuard {
    summary: RealtimeSummary,
    #[cfg(target_os = "linux")]
    restore: Option<linux::Saved>,
}

impl RealtimeGuard {
    /// Nothing asked (`--no-realtime`): the thread stays as it is.
    pub fn off() -> Self {
        RealtimeGuard {
            summary: RealtimeSummary::default(),
            #[cfg(target_os = "linux")]
            restore: None,
        }
    }

    /// Raises the calling thread to `SCHED_FIFO` at `priority` and locks the process's
    /// memory (now and from now on), each where the OS allows it.
    pub fn enter(priority: i32) -> Self {
        let mut summary = RealtimeSummary {
            requested: true,
            priority,
            ..RealtimeSummary::default()
        };
        #[cfg(target_os = "linux")]
        {
            let restore = match linux::set_fifo(priority) {
                Ok(saved) => {
                    summary.sched_fifo = true;
                    Some(saved)
                }
                Err(why) => {
                    summary.sched_fifo_refused = Some(why);
                    None
                }
            };
            match linux::lock_memory() {
                Ok(()) => summary.memory_locked = true,
                Err(why) => summary.memory_lock_refused = Some(why),
            }
            RealtimeGuard { summary, restore }
        }
        #[cfg(not(target_os = "linux"))]
        {
            let why = "not supported on this OS (Linux only)".to_string();
            summary.sched_fifo_refused = Some(why.clone());
            summary.memory_lock_refused = Some(why);
            RealtimeGuard { summary }
        }
    }

    pub fn summary(&self) -> &RealtimeSummary {
        &self.summary
    }

    /// The operator's warning when something asked for was refused; `None` when all was
    /// granted or nothing asked.
    pub fn warning(&self) -> Option<String> {
        let s = &self.summary;
        let mut refused = Vec::new();
        if let Some(why) = &s.sched_fifo_refused {
            refused.push(format!("SCHED_FIFO priority {} refused: {why}", s.priority));
        }
        if let Some(why) = &s.memory_lock_refused {
            refused.push(format!("memory not locked: {why}"));
        }
        (!refused.is_empty()).then(|| {
            format!(
                "the stepping thread is not real time ({}); other load on this machine can \
                 delay commands (--no-realtime silences this)",
                refused.join("; ")
            )
        })
    }
}

impl Drop for RealtimeGuard {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        {
            if let Some(saved) = self.restore.take() {
                linux::restore(saved);
            }
            if self.summary.memory_locked {
                linux::unlock_memory();
            }
        }
    }
}

#[cfg(target_os = "linux")]
mod linux {
    use std::io;

    /// The thread's policy and parameters before it was raised.
    pub struct Saved {
        policy: libc::c_int,
        param: libc::sched_param,
    }

    fn errno_text(code: libc::c_int) -> String {
        io::Error::from_raw_os_error(code).to_string()
    }

    /// `pthread_setschedparam(3)` on the calling thread. It returns the error number
    /// rather than setting errno.
    pub fn set_fifo(priority: i32) -> Result<Saved, String> {
        // SAFETY: pthread_self() is always the calling thread; the out-pointers are valid
        // locals, and sched_param is plain data for which all-zero is a valid value.
        unsafe {
            let me = libc::pthread_self();
            let mut policy = 0;
            let mut param: libc::sched_param = std::mem::zeroed();
            let rc = libc::pthread_getschedparam(me, &mut policy, &mut param);
            if rc != 0 {
                return Err(format!("reading the thread's policy: {}", errno_text(rc)));
            }
            let mut fifo: libc::sched_param = std::mem::zeroed();
            fifo.sched_priority = priority;
            match libc::pthread_setschedparam(me, libc::SCHED_FIFO, &fifo) {
                0 => Ok(Saved { policy, param }),
                libc::EINVAL => Err(format!(
                    "priority {priority} is outside SCHED_FIFO's range {}–{}",
                    libc::sched_get_priority_min(libc::SCHED_FIFO),
                    libc::sched_get_priority_max(libc::SCHED_FIFO)
                )),
                libc::EPERM => Err(format!(
                    "not permitted: it needs CAP_SYS_NICE (root) or a real-time priority \
                     limit of at least {priority} (`ulimit -r`, now {}; \
                     /etc/security/limits.conf `rtprio`)",
                    rlimit_text(libc::RLIMIT_RTPRIO, 1)
                )),
                rc => Err(errno_text(rc)),
            }
        }
    }

    pub fn restore(saved: Saved) {
        // SAFETY: as in set_fifo; the parameters are the ones the OS gave back. Going back
        // to the previous, less privileged policy is always permitted.
        unsafe {
            libc::pthread_setschedparam(libc::pthread_self(), saved.policy, &saved.param);
        }
    }

    /// `mlockall(MCL_CURRENT | MCL_FUTURE)` only where no limit applies. Under a finite
    /// `RLIMIT_MEMLOCK` without CAP_IPC_LOCK the kernel may accept MCL_FUTURE and then fail a
    /// later allocation that would pass the limit (mlockall(2)): an allocation failure in
    /// the middle of a flight is worse than a page fault.
    pub fn lock_memory() -> Result<(), String> {
        let limit = rlimit(libc::RLIMIT_MEMLOCK);
        let unlimited = limit.is_none_or(|l| l == libc::RLIM_INFINITY);
        if !unlimited && !has_capability(CAP_IPC_LOCK) {
            return Err(format!(
                "the locked-memory limit is {} KiB without CAP_IPC_LOCK: locking all memory \
                 under it would make later allocations fail (`ulimit -l unlimited`, or run \
                 as root)",
                limit.unwrap_or(0) / 1024
            ));
        }
        // SAFETY: mlockall takes flags only.
        if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
            Ok(())
        } else {
            Err(format!("mlockall: {}", io::Error::last_os_error()))
        }
    }

    pub fn unlock_memory() {
        // SAFETY: no arguments; undoes mlockall for the whole process.
        unsafe {
            libc::munlockall();
        }
    }

    /// The soft limit, `None` if it cannot be read.
    fn rlimit(resource: libc::__rlimit_resource_t) -> Option<libc::rlim_t> {
        let mut r = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: r is a valid out-pointer.
        (unsafe { libc::getrlimit(resource, &mut r) } == 0).then_some(r.rlim_cur)
    }

    fn rlimit_text(resource: libc::__rlimit_resource_t, unit: u64) -> String {
        match rlimit(resource) {
            Some(libc::RLIM_INFINITY) => "unlimited".to_string(),
            Some(v) => (v / unit).to_string(),
            None => "unknown".to_string(),
        }
    }

    /// capabilities(7): CAP_IPC_LOCK lifts RLIMIT_MEMLOCK.
    const CAP_IPC_LOCK: u32 = 14;

    /// Whether the process holds `cap` in its effective set (`CapEff` of /proc/self/status).
    fn has_capability(cap: u32) -> bool {
        std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| {
                let hex = s.lines().find_map(|l| l.strip_prefix("CapEff:"))?.trim();
                u64::from_str_radix(hex, 16).ok()
            })
            .is_some_and(|mask| mask & (1 << cap) != 0)
    }

    #[cfg(test)]
    pub fn current_policy() -> (libc::c_int, libc::c_int) {
        // SAFETY: as in set_fifo.
        unsafe {
            let mut policy = 0;
            let mut param: libc::sched_param = std::mem::zeroed();
            assert_eq!(
                libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param),
                0
            );
            (policy, param.sched_priority)
        }
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// On a thread of its own, so that the test runner's threads are never raised.
    fn on_a_thread<T: Send>(f: impl FnOnce() -> T + Send) -> T {
        std::thread::scope(|s| s.spawn(f).join().unwrap())
    }

    #[test]
    fn a_priority_out_of_range_is_refused_with_the_range_and_the_thread_left_as_it_was() {
        on_a_thread(|| {
            let before = linux::current_policy();
            let guard = RealtimeGuard::enter(0);
            let s = guard.summary();
            assert!(s.requested && !s.sched_fifo, "{s:?}");
            let why = s.sched_fifo_refused.as_deref().unwrap();
            assert!(why.contains("outside SCHED_FIFO's range 1–99"), "{why}");
            assert_eq!(linux::current_policy(), before);
            let warning = guard.warning().unwrap();
            assert!(
                warning.contains("SCHED_FIFO priority 0 refused"),
                "{warning}"
            );
        });
    }

    /// Granted (as root, or with rtprio allowed) or refused for want of the privilege; in
    /// both cases the OS's own view of the thread agrees with the summary, and dropping
    /// the guard restores the policy.
    #[test]
    fn the_thread_is_raised_as_the_summary_says_and_restored_on_drop() {
        on_a_thread(|| {
            let before = linux::current_policy();
            let guard = RealtimeGuard::enter(DEFAULT_PRIORITY);
            let s = guard.summary().clone();
            if s.sched_fifo {
                assert_eq!(
                    linux::current_policy(),
                    (libc::SCHED_FIFO, DEFAULT_PRIORITY)
                );
                assert_eq!(s.sched_fifo_refused, None);
            } else {
                let why = s.sched_fifo_refused.as_deref().unwrap();
                assert!(why.contains("not permitted"), "{why}");
                assert_eq!(linux::current_policy(), before);
            }
            assert_eq!(s.memory_locked, s.memory_lock_refused.is_none(), "{s:?}");
            assert_eq!(guard.warning().is_none(), s.sched_fifo && s.memory_locked);
            drop(guard);
            assert_eq!(linux::current_policy(), before);
        });
    }

    #[test]
    fn off_asks_nothing_and_warns_of_nothing() {
        let guard = RealtimeGuard::off();
        assert_eq!(guard.summary(), &RealtimeSummary::default());
        assert!(!guard.summary().requested);
        assert_eq!(guard.warning(), None);
    }
}
