//! Real-time scheduling for the processes that keep time with motors. On a loaded computer
//! the kernel's fair scheduler may hold a process back for tens to hundreds of
//! milliseconds, longer than a drive's watchdog or a bridge's lookahead: a robot's
//! controller runs its gait, bridges and gateways at a real-time priority (SCHED_FIFO), as
//! the fake devices of the tests do too (a device's processor is not held up by the host's
//! load). Their loops sleep between ticks, so they leave the processor to the rest.

use std::sync::OnceLock;

/// What the request made of the process's scheduling, for the log once logging is up.
static OUTCOME: OnceLock<Result<u8, String>> = OnceLock::new();

/// Puts the whole process (the calling thread and every thread it starts afterwards) under
/// SCHED_FIFO at `priority` (1 to 99); 0 leaves it as it is. A refusal (no CAP_SYS_NICE and
/// no rtprio limit) is no error: the process runs at normal priority and says so.
pub fn request(priority: u8) -> Result<(), String> {
    if priority == 0 {
        return Ok(());
    }
    let param = libc::sched_param {
        sched_priority: i32::from(priority.min(99)),
    };
    // SAFETY: sched_setscheduler(2) on this process with a valid parameter block.
    let r = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    let outcome = if r == 0 {
        Ok(priority)
    } else {
        Err(format!(
            "real-time priority {priority} refused ({}): running at normal priority (it \
             needs CAP_SYS_NICE or an rtprio limit, see README)",
            std::io::Error::last_os_error()
        ))
    };
    let _ = OUTCOME.set(outcome.clone());
    outcome.map(drop)
}

/// [`request`] at the priority `STRIDE_RT_PRIORITY` names, if it does (for device fakes
/// and tools with their own command line).
pub fn request_from_env() -> Result<(), String> {
    match std::env::var("STRIDE_RT_PRIORITY") {
        Ok(v) => match v.trim().parse::<u8>() {
            Ok(p) if p <= 99 => request(p),
            _ => Err(format!("STRIDE_RT_PRIORITY={v:?}: a priority from 0 to 99")),
        },
        Err(_) => Ok(()),
    }
}

/// Logs what [`request`] did, once logging is up.
pub(crate) fn log_outcome() {
    match OUTCOME.get() {
        Some(Ok(p)) => tracing::info!(priority = p, "running at real-time priority (SCHED_FIFO)"),
        Some(Err(why)) => tracing::warn!("{why}"),
        None => {}
    }
}
