//! Whether this process's run has begun, for a stop request (Ctrl-C, SIGTERM) to choose how
//! it ends. Before the run begins (the configuration, a saved map or a recording being read,
//! the scene being built, the simulator starting, a live-view client awaited) the run has
//! produced nothing, and none of those steps looks at the stop flag: the binary's
//! handler then ends the process at once ([`abandon_start`]). From the moment the pipeline is
//! about to be fed ([`begin_run`], called by `run_daemon`), a stop request drains the run and
//! its outputs and summary are written. No IO.

use std::sync::atomic::{AtomicU8, Ordering};

/// A run's start, claimed once either way: by the run beginning or by a stop request.
#[derive(Debug)]
pub struct StartGate(AtomicU8);

/// Nothing has begun and nothing has been stopped.
const STARTING: u8 = 0;
/// A run has begun: stop requests go through the run's stop flag.
const RUNNING: u8 = 1;
/// A stop request came first: no run will begin.
const ABANDONED: u8 = 2;

impl StartGate {
    /// A gate before anything has begun.
    pub const fn new() -> Self {
        Self(AtomicU8::new(STARTING))
    }

    /// For a stop request: true when no run has begun, and from now on none will (the caller
    /// ends the process); false once a run has begun (stop it through its stop flag).
    pub fn abandon(&self) -> bool {
        match self
            .0
            .compare_exchange(STARTING, ABANDONED, Ordering::AcqRel, Ordering::Acquire)
        {
            Ok(_) => true,
            Err(now) => now == ABANDONED,
        }
    }

    /// For a run about to begin: true when it may (also when another run in this process
    /// already began, as in tests that run several daemons); false when a stop request
    /// abandoned the start first.
    pub fn begin(&self) -> bool {
        match self
            .0
            .compare_exchange(STARTING, RUNNING, Ordering::AcqRel, Ordering::Acquire)
        {
            Ok(_) => true,
            Err(now) => now == RUNNING,
        }
    }

    /// Whether a stop request abandoned the start.
    pub fn is_abandoned(&self) -> bool {
        self.0.load(Ordering::Acquire) == ABANDONED
    }
}

impl Default for StartGate {
    fn default() -> Self {
        Self::new()
    }
}

/// The process's gate: signals are the process's.
static START: StartGate = StartGate::new();

/// For the binary's stop handler: true when no run has begun in this process, and then none
/// will (`run_daemon` gives up with `SourceError::Stopped` where it would have begun): the
/// caller ends the process. False once a run has begun: set its stop flag instead.
pub fn abandon_start() -> bool {
    START.abandon()
}

/// Whether a stop request abandoned this process's start ([`abandon_start`]).
pub fn start_abandoned() -> bool {
    START.is_abandoned()
}

/// Called by `run_daemon` just before the pipeline is fed: false when a stop request came
/// first.
pub(crate) fn begin_run() -> bool {
    START.begin()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_before_the_run_begins_abandons_it_and_the_run_does_not_begin() {
        let gate = StartGate::new();
        assert!(!gate.is_abandoned());
        assert!(gate.abandon());
        assert!(gate.is_abandoned());
        // A second request (Ctrl-C after SIGTERM) still finds the start abandoned.
        assert!(gate.abandon());
        assert!(!gate.begin(), "a run began after its start was abandoned");
    }

    #[test]
    fn a_stop_after_the_run_began_goes_to_the_run() {
        let gate = StartGate::new();
        assert!(gate.begin());
        assert!(!gate.abandon(), "a running run was abandoned");
        assert!(!gate.is_abandoned());
        // Another daemon in the same process (tests) begins too.
        assert!(gate.begin());
    }

    #[test]
    fn the_start_is_claimed_exactly_once_when_both_race() {
        for _ in 0..200 {
            let gate = std::sync::Arc::new(StartGate::new());
            let g = std::sync::Arc::clone(&gate);
            let stopper = std::thread::spawn(move || g.abandon());
            let began = gate.begin();
            let abandoned = stopper.join().unwrap();
            assert!(began != abandoned, "began {began}, abandoned {abandoned}");
        }
    }
}
