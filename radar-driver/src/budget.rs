//! The driver's memory budget, in bytes: what the radar sends can be held only within it.
//!
//! Counts bound nothing when an azimuth can be anything from 0 bytes to just under 1 MB
//! (the largest payload the protocol accepts): 4096 queued azimuths of the largest legal
//! size are 4 GB. So every azimuth the driver hands out carries a [`Charge`] on one
//! [`ByteBudget`]:
//!
//! - its bins are copied out of the socket's read buffer into an allocation of their own
//!   (a small azimuth never pins the large buffer it was decoded from: the allocation
//!   behind a `Bytes` slice cannot be seen, so no slice of a read buffer is handed out);
//! - that allocation carries the charge: its bins plus [`AZIMUTH_OVERHEAD_BYTES`] (the
//!   azimuth's own struct, its place in a rotation's vector, the allocation's header);
//! - the charge is released when the last copy of the azimuth is dropped, wherever that
//!   is: in a channel, in a rotation being assembled or queued, or in a consumer's hands;
//! - the channels' slot arrays are charged once, when the driver is built
//!   ([`crate::HandoffSettings::slot_bytes`]), and chunks queued for the recording file
//!   are charged like azimuths.
//!
//! When a charge does not fit, the azimuth (or recording chunk) is dropped, counted in
//! [`crate::MetricsSnapshot::budget_drops`] and logged rate-limited; under drop-oldest
//! the oldest queued items are dropped first to make room. The bytes held never exceed
//! the limit: [`ByteBudget::peak`] is the proof a test reads.
//!
//! Not counted (bounded by constants, not by the wire): the read buffer of the one live
//! connection (at most one frame, under 1 MB, plus two read chunks), the socket's receive
//! buffer (`recv_buffer_bytes`), and the geometry (one per configuration).

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

use bytes::Bytes;

use crate::azimuth::Azimuth;

/// Bytes charged per azimuth on top of its bins: its struct twice (once where it lies, once
/// for a rotation vector's spare capacity) and 64 for the shared allocation's header.
pub const AZIMUTH_OVERHEAD_BYTES: usize = 2 * std::mem::size_of::<Azimuth>() + 64;

/// A limit on the bytes held, shared by everything that holds them. Lock-free.
#[derive(Debug)]
pub struct ByteBudget {
    limit: usize,
    held: AtomicUsize,
    peak: AtomicUsize,
    refused: AtomicU64,
}

impl Default for ByteBudget {
    /// No limit (`usize::MAX`): counts only.
    fn default() -> Self {
        Self {
            limit: usize::MAX,
            held: AtomicUsize::new(0),
            peak: AtomicUsize::new(0),
            refused: AtomicU64::new(0),
        }
    }
}

impl ByteBudget {
    /// A budget of `limit` bytes.
    pub fn new(limit: usize) -> Arc<Self> {
        Arc::new(Self {
            limit,
            held: AtomicUsize::new(0),
            peak: AtomicUsize::new(0),
            refused: AtomicU64::new(0),
        })
    }

    /// Takes `bytes` from the budget if they fit; the [`Charge`] gives them back when
    /// dropped. `None` (counted in [`ByteBudget::refused`]) when they do not fit.
    pub fn try_charge(self: &Arc<Self>, bytes: usize) -> Option<Charge> {
        let mut held = self.held.load(Ordering::Relaxed);
        loop {
            let after = match held.checked_add(bytes) {
                Some(after) if after <= self.limit => after,
                _ => {
                    self.refused.fetch_add(1, Ordering::Relaxed);
                    return None;
                }
            };
            match self
                .held
                .compare_exchange_weak(held, after, Ordering::AcqRel, Ordering::Relaxed)
            {
                Ok(_) => {
                    self.peak.fetch_max(after, Ordering::Relaxed);
                    return Some(Charge {
                        budget: Arc::clone(self),
                        bytes,
                    });
                }
                Err(now) => held = now,
            }
        }
    }

    /// A copy of `data` in an allocation of its own that carries a charge of its length
    /// plus `overhead`; `None` when that does not fit (nothing is allocated then).
    pub fn copy(self: &Arc<Self>, data: &[u8], overhead: usize) -> Option<Bytes> {
        let charge = self.try_charge(data.len().saturating_add(overhead))?;
        Some(Bytes::from_owner(Charged {
            data: Box::from(data),
            _charge: charge,
        }))
    }

    /// The limit, bytes.
    pub fn limit(&self) -> usize {
        self.limit
    }

    /// Bytes held now.
    pub fn held(&self) -> usize {
        self.held.load(Ordering::Relaxed)
    }

    /// The most bytes ever held at once.
    pub fn peak(&self) -> usize {
        self.peak.load(Ordering::Relaxed)
    }

    /// Charges refused because they did not fit.
    pub fn refused(&self) -> u64 {
        self.refused.load(Ordering::Relaxed)
    }
}

/// Bytes taken from a [`ByteBudget`], given back on drop.
#[derive(Debug)]
pub struct Charge {
    budget: Arc<ByteBudget>,
    bytes: usize,
}

impl Charge {
    /// The bytes this charge holds.
    pub fn bytes(&self) -> usize {
        self.bytes
    }
}

impl Drop for Charge {
    fn drop(&mut self) {
        self.budget.held.fetch_sub(self.bytes, Ordering::AcqRel);
    }
}

/// An owned copy carrying its charge: the owner behind a charged [`Bytes`].
struct Charged {
    data: Box<[u8]>,
    _charge: Charge,
}

impl AsRef<[u8]> for Charged {
    fn as_ref(&self) -> &[u8] {
        &self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_charge_that_does_not_fit_is_refused_and_one_dropped_gives_its_bytes_back() {
        let budget = ByteBudget::new(100);
        let a = budget.try_charge(60).unwrap();
        assert!(budget.try_charge(41).is_none());
        let b = budget.try_charge(40).unwrap();
        assert_eq!(
            (budget.held(), budget.peak(), budget.refused()),
            (100, 100, 1)
        );
        drop(a);
        assert_eq!(budget.held(), 40);
        drop(b);
        assert_eq!((budget.held(), budget.peak()), (0, 100));
        assert!(budget.try_charge(usize::MAX).is_none(), "no overflow");
    }

    #[test]
    fn a_copy_is_charged_once_however_often_it_is_cloned_until_the_last_clone_goes() {
        let budget = ByteBudget::new(1 << 20);
        let source = Bytes::from(vec![7u8; 4096]);
        let small = source.slice(10..30);
        let copy = budget.copy(&small, 8).unwrap();
        assert_eq!(&copy[..], &small[..]);
        assert_eq!(budget.held(), 28);
        let clones: Vec<Bytes> = (0..10).map(|_| copy.clone()).collect();
        let sliced = copy.slice(2..5);
        assert_eq!(budget.held(), 28);
        drop(copy);
        drop(clones);
        assert_eq!(budget.held(), 28, "a slice still holds the copy");
        drop(sliced);
        assert_eq!(budget.held(), 0);
    }

    #[test]
    fn the_budget_holds_across_threads() {
        let budget = ByteBudget::new(1000);
        let threads: Vec<_> = (0..4)
            .map(|_| {
                let budget = Arc::clone(&budget);
                std::thread::spawn(move || {
                    for _ in 0..10_000 {
                        if let Some(c) = budget.try_charge(300) {
                            assert!(budget.held() <= 1000);
                            drop(c);
                        }
                    }
                })
            })
            .collect();
        for t in threads {
            t.join().unwrap();
        }
        assert_eq!(budget.held(), 0);
        assert!(budget.peak() <= 1000);
    }
}
