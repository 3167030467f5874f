//! The driver: connects, serves the connection, and reconnects with backoff, forever by
//! default, until its [`ShutdownTrigger`] fires.

use std::sync::Arc;

use crate::assembly::RotationAssembler;
use crate::backoff::Backoff;
use crate::clock::{Clock, SystemClock};
use crate::error::{DriverError, ErrorChain, SessionError, SettingsError};
use crate::handoff::{ChannelSink, Receivers, Sink};
use crate::metrics::{Metrics, MetricsSnapshot};
use crate::record::{RecordSummary, Recorder};
use crate::session::{LogLimits, SessionEnd, SessionState};
use crate::settings::DriverSettings;
use crate::shutdown::{shutdown_pair, Shutdown, ShutdownTrigger};
use crate::socket::connect;

/// The radar's last configuration, `None` before the first.
pub type ConfigurationWatch = tokio::sync::watch::Receiver<Option<Arc<protocol::Configuration>>>;

/// How the driver ended after a shutdown.
#[derive(Debug, Clone, PartialEq)]
pub struct DriverExit {
    /// The counters at the end.
    pub metrics: MetricsSnapshot,
    /// The recording, when one was made.
    pub recording: Option<RecordSummary>,
}

/// A configured driver, ready to run.
#[derive(Debug)]
pub struct Driver {
    state: SessionState,
}

impl Driver {
    /// A driver delivering into crossbeam channels per `settings.handoff`; returns the
    /// receivers for the consumers.
    pub fn new(settings: DriverSettings) -> (Self, Receivers) {
        let (sink, receivers) = ChannelSink::new(settings.handoff);
        (Self::with_sink(settings, Box::new(sink)), receivers)
    }

    /// A driver delivering into any [`Sink`].
    pub fn with_sink(settings: DriverSettings, sink: Box<dyn Sink>) -> Self {
        let settings_log_interval = settings.log_interval;
        let max_held_bytes = settings.max_held_bytes;
        Self {
            state: SessionState {
                settings,
                sink,
                clock: Arc::new(SystemClock::new()),
                metrics: Arc::new(Metrics::with_budget(max_held_bytes)),
                recorder: None,
                assembler: RotationAssembler::new(),
                geometry: None,
                configuration_tx: tokio::sync::watch::channel(None).0,
                overlong_rotations: 0,
                logs: LogLimits::new(settings_log_interval),
            },
        }
    }

    /// Replaces the clock (tests).
    pub fn with_clock(mut self, clock: Arc<dyn Clock>) -> Self {
        self.state.clock = clock;
        self
    }

    /// The live counters.
    pub fn metrics(&self) -> Arc<Metrics> {
        Arc::clone(&self.state.metrics)
    }

    /// The radar's configuration as last received (`None` until the first one): a watch
    /// that changes whenever the radar sends it again.
    pub fn configuration(&self) -> ConfigurationWatch {
        self.state.configuration_tx.subscribe()
    }

    /// Runs on the current tokio runtime; returns a handle to stop it and read its metrics.
    pub fn spawn(self) -> DriverHandle {
        let (trigger, shutdown) = shutdown_pair();
        let metrics = self.metrics();
        let configuration = self.configuration();
        let task = tokio::spawn(self.run(shutdown));
        DriverHandle {
            trigger,
            metrics,
            configuration,
            task: Some(task),
        }
    }

    /// Runs until `shutdown` fires (then `Ok`) or the attempts run out (then `Err`).
    pub async fn run(mut self, mut shutdown: Shutdown) -> Result<DriverExit, DriverError> {
        self.state.settings.validate()?;
        // The sink's slot arrays are held for the whole run: charged once.
        let slot_bytes = self.state.sink.fixed_bytes();
        let _slots = self.state.metrics.budget().try_charge(slot_bytes).ok_or(
            SettingsError::BudgetBelowChannels {
                slot_bytes,
                max_held_bytes: self.state.settings.max_held_bytes,
            },
        )?;
        if let Some(path) = self.state.settings.record_path.clone() {
            let recorder = Recorder::create(&path).map_err(|source| DriverError::Record {
                path: path.clone(),
                source,
            })?;
            tracing::info!(path = %path.display(), "recording the raw byte stream");
            self.state.recorder = Some(recorder);
        }
        let result = self.reconnect_loop(&mut shutdown).await;
        if let Some(partial) = self.state.assembler.flush() {
            self.state.deliver_rotation(partial);
        }
        let recording = match self.state.recorder.take() {
            // Joining the writer thread blocks: do it on the blocking pool.
            Some(r) => Some(tokio::task::spawn_blocking(move || r.finish()).await?),
            None => None,
        };
        result.map(|()| DriverExit {
            metrics: self.state.metrics.snapshot(),
            recording,
        })
    }

    async fn reconnect_loop(&mut self, shutdown: &mut Shutdown) -> Result<(), DriverError> {
        let settings = self.state.settings.clone();
        let metrics = Arc::clone(&self.state.metrics);
        let mut backoff = Backoff::new(settings.backoff);
        let mut failures_in_a_row = 0u32;
        let mut connected_before = false;
        loop {
            if shutdown.is_triggered() {
                return Ok(());
            }
            metrics.add_connect_attempts(1);
            tracing::info!(address = %settings.address, attempt = failures_in_a_row + 1, "connecting to the radar");
            let connected = tokio::select! {
                biased;
                () = shutdown.triggered() => return Ok(()),
                c = connect(settings.address, &settings.socket) => c,
            };
            let error: SessionError = match connected {
                Ok(stream) => {
                    metrics.add_connections(1);
                    if connected_before {
                        metrics.add_reconnects(1);
                    }
                    connected_before = true;
                    tracing::info!(address = %settings.address, "connected");
                    let outcome = self.state.serve(stream, shutdown).await;
                    if outcome.configured {
                        backoff.reset();
                        failures_in_a_row = 0;
                    }
                    match outcome.end {
                        Ok(SessionEnd::Shutdown) => return Ok(()),
                        Err(e) => e,
                    }
                }
                Err(e) => e,
            };
            failures_in_a_row = failures_in_a_row.saturating_add(1);
            if let Some(max) = settings.max_attempts {
                if failures_in_a_row >= max.get() {
                    tracing::error!(attempts = failures_in_a_row, error = %ErrorChain(&error), "giving up on the radar");
                    return Err(DriverError::GaveUp {
                        attempts: failures_in_a_row,
                        last: error,
                    });
                }
            }
            let delay = backoff.next_delay();
            crate::warn_limited!(
                self.state.logs.link_lost,
                address = %settings.address,
                failures_in_a_row,
                delay_ms = u64::try_from(delay.as_millis()).unwrap_or(u64::MAX),
                error = %ErrorChain(&error),
                "radar link lost; reconnecting"
            );
            tokio::select! {
                biased;
                () = shutdown.triggered() => return Ok(()),
                () = tokio::time::sleep(delay) => {}
            }
        }
    }
}

/// Controls a spawned driver. Dropping the handle stops the driver (as
/// [`DriverHandle::shutdown`] does) without waiting for it.
#[derive(Debug)]
pub struct DriverHandle {
    trigger: ShutdownTrigger,
    metrics: Arc<Metrics>,
    configuration: ConfigurationWatch,
    /// Taken by `join`.
    task: Option<tokio::task::JoinHandle<Result<DriverExit, DriverError>>>,
}

impl Drop for DriverHandle {
    fn drop(&mut self) {
        self.trigger.trigger();
    }
}

impl DriverHandle {
    /// A copy of the counters now.
    pub fn metrics(&self) -> MetricsSnapshot {
        self.metrics.snapshot()
    }

    /// The live counters.
    pub fn metrics_handle(&self) -> Arc<Metrics> {
        Arc::clone(&self.metrics)
    }

    /// The radar's configuration as last received.
    pub fn configuration(&self) -> ConfigurationWatch {
        self.configuration.clone()
    }

    /// A listener on this driver's shutdown, for tasks that should stop with it.
    pub fn shutdown_listener(&self) -> Shutdown {
        self.trigger.subscribe()
    }

    /// Asks the driver to stop: it sends stop FFT data (22) and closes.
    pub fn shutdown(&self) {
        self.trigger.trigger();
    }

    /// Waits for the driver to end (it ends by itself only when it gives up).
    pub async fn join(mut self) -> Result<DriverExit, DriverError> {
        match self.task.take() {
            Some(task) => task.await?,
            None => Err(DriverError::AlreadyJoined),
        }
    }

    /// Stops the driver and waits for it.
    pub async fn stop(self) -> Result<DriverExit, DriverError> {
        self.shutdown();
        self.join().await
    }
}
