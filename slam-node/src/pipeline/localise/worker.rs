//! The place search on a thread of its own, so that tracking never waits for it.
//!
//! [`SearchWorker`] owns the [`PlaceSearcher`] on a `std` thread fed by a bounded
//! crossbeam channel, as slam-graph's global layer runs: the pipeline thread only
//! `try_send`s a request (the local map and the vehicle's pose in it) and `try_recv`s the
//! outcome, once a rotation, with at most one attempt in flight. Requests carry the local
//! frame they were made in; a frame restarted in between (the search window, or a new
//! search after a lost fix) is told to the worker in order, and an outcome from an
//! earlier frame is carried into the current one by the caller or dropped.
//!
//! When the stream runs ahead of the wall clock (a simulation or a replay as fast as
//! possible), the outcome is waited for and applied at the first rotation whose stream time
//! is at least the request's plus the search's measured wall time: what a real-time run
//! would see, whatever the replay speed. In real time nothing waits. No IO.

use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver, Sender, TryRecvError, TrySendError};
use radar_model::geometry::Pose2;
use slam_filter::FrozenSubmap;
use tracing::warn;

use super::known::MapFeatures;
use super::scan_search::{local_scan, KeptCloud, ScanSearcher};
use super::search::{Attempt, PlaceSearcher};

/// The stream ahead of the wall clock by more than this (s) since a request: not a
/// real-time run, the outcome is waited for.
const AHEAD_S: f64 = 1.0;
/// Waiting for an outcome gives up after this (a worker gone wrong never hangs the run).
const WAIT_AT_MOST: Duration = Duration::from_secs(60);

/// What an attempt searches with.
#[derive(Debug)]
pub enum Query {
    /// The local map's features (the feature search).
    Features(FrozenSubmap),
    /// The last stretch's clouds with the local filter's poses (the scan search).
    Scans(Vec<KeptCloud>),
}

/// The search the thread runs.
#[derive(Debug)]
pub enum Search {
    /// Over the map's features.
    Features(PlaceSearcher, Arc<MapFeatures>),
    /// Over the map's scans.
    Scans(ScanSearcher),
}

impl Search {
    fn attempt(&mut self, query: &Query, vehicle: &Pose2) -> Attempt {
        match (self, query) {
            (Search::Features(searcher, map), Query::Features(local)) => {
                searcher.attempt(map, local, vehicle)
            }
            (Search::Scans(searcher), Query::Scans(clouds)) => {
                let local = local_scan(clouds, vehicle, searcher.scan_settings());
                searcher.attempt(&local, vehicle)
            }
            // A query of the other kind: nothing to search with.
            _ => Attempt::TooFewFeatures,
        }
    }

    fn reframe(&mut self, origin: &Pose2) {
        match self {
            Search::Features(s, _) => s.reframe(origin),
            Search::Scans(s) => s.reframe(origin),
        }
    }

    fn forget(&mut self) {
        match self {
            Search::Features(s, _) => s.forget(),
            Search::Scans(s) => s.forget(),
        }
    }
}

enum Request {
    Attempt {
        frame: u64,
        query: Box<Query>,
        vehicle: Pose2,
    },
    /// The local frame restarted at `origin` (in the old one).
    Reframe(Pose2),
    /// The search starts again: a pending candidate is forgotten.
    Forget,
}

/// An attempt's outcome.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    /// The local frame the request was made in.
    pub frame: u64,
    /// What the attempt found (transforms of that frame into the map's).
    pub attempt: Attempt,
    /// The attempt's wall time on the worker (s).
    pub wall_s: f64,
}

struct InFlight {
    stream_s: f64,
    sent: Instant,
    received: Option<Outcome>,
}

/// The place search's thread.
pub struct SearchWorker {
    requests: Option<Sender<Request>>,
    outcomes: Receiver<Outcome>,
    thread: Option<JoinHandle<()>>,
    in_flight: Option<InFlight>,
    /// Attempts' wall times on the worker (s), for the summary.
    pub wall_s: Vec<f64>,
}

impl std::fmt::Debug for SearchWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SearchWorker")
            .field("in_flight", &self.in_flight.is_some())
            .finish_non_exhaustive()
    }
}

impl SearchWorker {
    /// Starts the thread with the map's places.
    pub fn spawn(search: Search) -> std::io::Result<Self> {
        // Requests are few (one attempt in flight, and the frame changes in between).
        let (tx, rx) = bounded::<Request>(16);
        let (out_tx, out_rx) = bounded::<Outcome>(4);
        let thread = std::thread::Builder::new()
            .name("place-search".into())
            .spawn(move || {
                let mut search = search;
                for request in rx {
                    match request {
                        Request::Attempt {
                            frame,
                            query,
                            vehicle,
                        } => {
                            let start = Instant::now();
                            let attempt = search.attempt(&query, &vehicle);
                            let outcome = Outcome {
                                frame,
                                attempt,
                                wall_s: start.elapsed().as_secs_f64(),
                            };
                            if out_tx.send(outcome).is_err() {
                                return;
                            }
                        }
                        Request::Reframe(origin) => search.reframe(&origin),
                        Request::Forget => search.forget(),
                    }
                }
            })?;
        Ok(Self {
            requests: Some(tx),
            outcomes: out_rx,
            thread: Some(thread),
            in_flight: None,
            wall_s: Vec::new(),
        })
    }

    /// Whether an attempt is in flight (no other is sent until its outcome is taken).
    pub fn busy(&self) -> bool {
        self.in_flight.is_some()
    }

    fn send(&mut self, r: Request) -> bool {
        let Some(tx) = self.requests.as_ref() else {
            return false;
        };
        match tx.try_send(r) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                warn!("the place search's thread is gone or hopelessly behind: no attempt sent");
                false
            }
        }
    }

    /// Sends an attempt made in local frame `frame` at stream time `stream_s`; `false` when
    /// one is in flight or the thread is gone.
    pub fn submit(&mut self, frame: u64, query: Query, vehicle: Pose2, stream_s: f64) -> bool {
        if self.busy() {
            return false;
        }
        let sent = self.send(Request::Attempt {
            frame,
            query: Box::new(query),
            vehicle,
        });
        if sent {
            self.in_flight = Some(InFlight {
                stream_s,
                sent: Instant::now(),
                received: None,
            });
        }
        sent
    }

    /// The local frame restarted at `origin` (in the old one).
    pub fn reframe(&mut self, origin: Pose2) {
        self.send(Request::Reframe(origin));
    }

    /// The search starts again.
    pub fn forget(&mut self) {
        self.send(Request::Forget);
    }

    /// The outcome in flight, once it is due at stream time `stream_s` (see the module's
    /// note on runs faster than real time); `None` while it is not.
    pub fn poll(&mut self, stream_s: f64) -> Option<Outcome> {
        let f = self.in_flight.as_mut()?;
        if f.received.is_none() {
            let ahead = (stream_s - f.stream_s) - f.sent.elapsed().as_secs_f64();
            let got = if ahead > AHEAD_S {
                self.outcomes.recv_timeout(WAIT_AT_MOST).map_err(|_| ())
            } else {
                self.outcomes.try_recv().map_err(|e| {
                    if e == TryRecvError::Disconnected {
                        warn!("the place search's thread is gone");
                    }
                })
            };
            match got {
                Ok(o) => f.received = Some(o),
                Err(()) => {
                    if self.thread.as_ref().is_some_and(|t| t.is_finished()) {
                        // Nothing will come: free the slot so the caller can see it.
                        self.in_flight = None;
                    }
                    return None;
                }
            }
        }
        let o = f.received?;
        if stream_s - f.stream_s >= o.wall_s {
            self.in_flight = None;
            self.wall_s.push(o.wall_s);
            Some(o)
        } else {
            None
        }
    }
}

impl Drop for SearchWorker {
    fn drop(&mut self) {
        // Closing the channel ends the thread's loop after the attempt it is on.
        self.requests = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
