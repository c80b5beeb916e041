//! Asks the OS to run the calling thread with real-time priority. A 1 kHz haptic loop on a
//! loaded machine is otherwise descheduled for whole time slices (several ms), far past its
//! 1 ms deadline; real haptic drivers run their servo thread the same way. Without the
//! privilege (no root / CAP_SYS_NICE) the loop still runs, at normal priority.

/// Tries SCHED_FIFO at a middle priority for the calling thread; true if granted.
#[cfg(target_os = "linux")]
pub fn try_elevate() -> bool {
    let param = libc::sched_param { sched_priority: 50 };
    // SAFETY: sched_setscheduler reads `param` only during the call; pid 0 is this thread.
    let r = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    r == 0
}

#[cfg(not(target_os = "linux"))]
pub fn try_elevate() -> bool {
    false
}
