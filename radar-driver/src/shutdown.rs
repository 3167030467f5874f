//! A cancellation handle: one [`ShutdownTrigger`], any number of [`Shutdown`] listeners.

use tokio::sync::watch;

/// Fires the shutdown. Dropping it without calling [`ShutdownTrigger::trigger`] does not
/// cancel anything: listeners then wait forever.
#[derive(Debug)]
pub struct ShutdownTrigger {
    tx: watch::Sender<bool>,
}

/// Waits for the shutdown. Cheap to clone.
#[derive(Debug, Clone)]
pub struct Shutdown {
    /// `None`: a listener that never fires.
    rx: Option<watch::Receiver<bool>>,
}

/// A connected trigger and listener.
pub fn shutdown_pair() -> (ShutdownTrigger, Shutdown) {
    let (tx, rx) = watch::channel(false);
    (ShutdownTrigger { tx }, Shutdown { rx: Some(rx) })
}

impl ShutdownTrigger {
    /// Asks every listener to stop. Idempotent.
    pub fn trigger(&self) {
        self.tx.send_replace(true);
    }

    /// A new listener.
    pub fn subscribe(&self) -> Shutdown {
        Shutdown {
            rx: Some(self.tx.subscribe()),
        }
    }
}

impl Shutdown {
    /// A listener that never fires.
    pub fn never() -> Self {
        Shutdown { rx: None }
    }

    /// True once the shutdown was triggered.
    pub fn is_triggered(&self) -> bool {
        self.rx.as_ref().is_some_and(|rx| *rx.borrow())
    }

    /// Resolves when the shutdown is triggered (at once if it already was).
    pub async fn triggered(&mut self) {
        let Some(rx) = self.rx.as_mut() else {
            return std::future::pending::<()>().await;
        };
        loop {
            if *rx.borrow_and_update() {
                return;
            }
            if rx.changed().await.is_err() {
                // The trigger is gone without firing: nothing can fire any more.
                std::future::pending::<()>().await;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[tokio::test]
    async fn every_listener_sees_the_trigger() {
        let (trigger, a) = shutdown_pair();
        let mut b = trigger.subscribe();
        let mut a2 = a.clone();
        assert!(!a.is_triggered());
        trigger.trigger();
        tokio::time::timeout(Duration::from_secs(1), async {
            a2.triggered().await;
            b.triggered().await;
        })
        .await
        .unwrap();
        assert!(a.is_triggered());
    }

    #[tokio::test]
    async fn a_dropped_trigger_does_not_fire() {
        let (trigger, mut a) = shutdown_pair();
        drop(trigger);
        assert!(
            tokio::time::timeout(Duration::from_millis(50), a.triggered())
                .await
                .is_err()
        );
    }
}

/// Which request ended a process: see [`stop_signal`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopSignal {
    /// SIGINT: Ctrl-C at a terminal.
    CtrlC,
    /// SIGTERM: what `kill`, systemd and container runtimes send.
    Term,
}

impl std::fmt::Display for StopSignal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            StopSignal::CtrlC => "Ctrl-C",
            StopSignal::Term => "SIGTERM",
        })
    }
}

/// Resolves at the first request to stop the process: Ctrl-C, or on Unix SIGTERM, so that
/// a daemon stopped by its service manager ends as it does at a terminal (outputs written,
/// summary printed) instead of being killed mid-write. On Unix the handlers are installed
/// when this is called, not when the future is first polled: a request that comes between
/// the two is not lost (a binary can install them before it reads its inputs). Call it
/// inside a tokio runtime (as tokio's `signal` requires). If neither can be installed the
/// future never resolves (the default action then stands).
pub fn stop_signal() -> impl std::future::Future<Output = StopSignal> + Send + 'static {
    #[cfg(unix)]
    let handlers = {
        use tokio::signal::unix::{signal, SignalKind};
        (
            signal(SignalKind::interrupt()).ok(),
            signal(SignalKind::terminate()).ok(),
        )
    };
    async move {
        #[cfg(unix)]
        {
            let (mut interrupt, mut terminate) = handlers;
            tokio::select! {
                () = delivered(interrupt.as_mut()) => StopSignal::CtrlC,
                () = delivered(terminate.as_mut()) => StopSignal::Term,
            }
        }
        #[cfg(not(unix))]
        match tokio::signal::ctrl_c().await {
            Ok(()) => StopSignal::CtrlC,
            Err(_) => std::future::pending().await,
        }
    }
}

/// Resolves when `signal` is delivered; never without a handler, or once the runtime that
/// delivers it is gone.
#[cfg(unix)]
async fn delivered(signal: Option<&mut tokio::signal::unix::Signal>) {
    if let Some(s) = signal {
        if s.recv().await.is_some() {
            return;
        }
    }
    std::future::pending::<()>().await;
}
