//! Rotation assembly: azimuths in encoder order into [`Rotation`]s. Pure state, no IO.
//!
//! Rules:
//! - An encoder value smaller than the previous one starts a new rotation; the finished one
//!   is handed out then.
//! - Azimuth slots are `round(encoder x azimuth_samples / encoder_size)`. A jump of more
//!   than one slot counts the slots in between as skipped; so do the slots before the first
//!   azimuth and after the last one of a rotation that began at a wrap.
//! - The sweep counter should rise by one per azimuth message (wrapping at 65535); any
//!   other step is a gap, and its size (modulo 2^16) the number of messages missing. The
//!   counter is the radar's, so it is checked across reconnections too.
//! - A changed geometry (a re-sent configuration that differs) closes the rotation in
//!   progress as partial: encoder values of two geometries cannot be compared.
//! - A rotation is held to at most [`MAX_ROTATION_FACTOR`] times the configured azimuths: a
//!   radar whose encoder never wraps (stuck) gets its rotation closed as partial there
//!   instead of growing without bound.
//! - Rotations are held only when someone wants them ([`RotationAssembler::counting_only`]):
//!   otherwise only the skip and gap counts are kept, and no azimuth (nor the read buffer it
//!   was decoded from) is pinned.
//!
//! - Azimuths the driver's byte budget refused are counted and numbered but not held
//!   ([`RotationAssembler::push_unheld`], [`Rotation::dropped_azimuths`]).
//!
//! The assembler lives in the driver's session state and survives reconnections.

use std::sync::Arc;

use protocol::Geometry;

use crate::azimuth::{Azimuth, Rotation};

/// A rotation holds at most this many times the configured azimuths per rotation.
pub const MAX_ROTATION_FACTOR: usize = 2;

/// What one [`RotationAssembler::push`] found.
#[derive(Debug, Default)]
pub struct PushReport {
    /// The rotation the pushed azimuth belongs to (see [`Azimuth::rotation`]).
    pub rotation: u64,
    /// The rotation in progress reached [`MAX_ROTATION_FACTOR`] times the configured
    /// azimuths without its encoder wrapping, and was closed as partial.
    pub overlong: bool,
    /// A rotation finished by this azimuth (or by a geometry change it carried).
    pub finished: Option<Rotation>,
    /// Azimuth slots found missing by this push.
    pub skipped_azimuths: u32,
    /// Messages missing before this azimuth according to the sweep counter (0: none).
    pub sweep_missing: u32,
}

/// Assembles rotations. See the module documentation for the rules.
#[derive(Debug, Default)]
pub struct RotationAssembler {
    geometry: Option<Arc<Geometry>>,
    current: Vec<Azimuth>,
    next_sequence: u64,
    started_at_wrap: bool,
    last_encoder: Option<u16>,
    last_sweep: Option<u16>,
    skipped: u32,
    sweep_gaps: u32,
    sweep_missing: u32,
    duplicates: u32,
    /// Azimuths of the rotation in progress not held (refused by the byte budget).
    dropped: u32,
    /// Keep only the counts; hold no azimuth.
    counting_only: bool,
    /// Azimuths pushed into the rotation in progress (held or not).
    in_rotation: usize,
    /// Rotations begun: the number of the rotation in progress.
    rotation: u64,
}

/// The azimuth slot of an encoder value: `protocol`'s azimuth index (the last slot for a
/// value past the revolution, which the session has already refused).
fn slot(geometry: &Geometry, encoder: u16) -> u32 {
    geometry.azimuth_index(encoder).map_or_else(
        || u32::from(geometry.azimuth_samples).saturating_sub(1),
        u32::from,
    )
}

impl RotationAssembler {
    /// An empty assembler.
    pub fn new() -> Self {
        Self::default()
    }

    /// Azimuths held for the rotation in progress.
    pub fn pending(&self) -> usize {
        self.current.len()
    }

    /// When `true`, rotations are not assembled: only the skip and gap counts are kept and
    /// no azimuth is held (nobody asked for rotations).
    pub fn set_counting_only(&mut self, counting_only: bool) {
        self.counting_only = counting_only;
        if counting_only {
            self.current = Vec::new();
        }
    }

    /// Takes a (re-sent) geometry. If it differs from the one in force, the rotation in
    /// progress is closed as partial and returned.
    pub fn set_geometry(&mut self, geometry: Arc<Geometry>) -> Option<Rotation> {
        let changed = self.geometry.as_deref() != Some(&*geometry);
        let finished = if changed { self.flush() } else { None };
        self.geometry = Some(geometry);
        finished
    }

    /// Adds one azimuth (its geometry must be the one set last; a different one is taken
    /// as a geometry change).
    pub fn push(&mut self, mut azimuth: Azimuth) -> PushReport {
        let report = self.count(&azimuth);
        azimuth.rotation = report.rotation;
        if !self.counting_only {
            // No reservation from the wire's azimuth count: the vector grows with what
            // arrives (each azimuth's budget charge covers twice its struct).
            self.current.push(azimuth);
        }
        report
    }

    /// Numbers `azimuth` with its rotation (as [`RotationAssembler::push`] does) without
    /// holding it: the one place rotations are numbered, for azimuths that reach the daemon
    /// another way than the driver's session (a recording's replay, the evaluation).
    pub fn number(&mut self, azimuth: &mut Azimuth) -> PushReport {
        let report = self.count(azimuth);
        azimuth.rotation = report.rotation;
        report
    }

    /// Counts an azimuth that is not held (the driver's byte budget refused it): numbered
    /// and counted as [`RotationAssembler::push`] does, but missing from its rotation
    /// ([`Rotation::dropped_azimuths`]).
    pub fn push_unheld(&mut self, azimuth: &Azimuth) -> PushReport {
        let report = self.count(azimuth);
        self.dropped = self.dropped.saturating_add(1);
        report
    }

    fn count(&mut self, azimuth: &Azimuth) -> PushReport {
        let mut report = PushReport::default();
        if self.geometry.as_deref() != Some(&*azimuth.geometry) {
            report.finished = self.set_geometry(Arc::clone(&azimuth.geometry));
        }
        let geometry = Arc::clone(&azimuth.geometry);
        let now = slot(&geometry, azimuth.encoder);
        match self.last_encoder {
            Some(last) if azimuth.encoder < last => {
                let tail = u32::from(geometry.azimuth_samples)
                    .saturating_sub(1)
                    .saturating_sub(slot(&geometry, last));
                self.skipped = self.skipped.saturating_add(tail);
                report.skipped_azimuths += tail;
                // A geometry flush above leaves `last_encoder` empty, so at most one
                // rotation finishes per push.
                report.finished = self.close(true);
                self.started_at_wrap = true;
                self.skipped = now;
                report.skipped_azimuths += now;
            }
            Some(last) if azimuth.encoder == last => {
                self.duplicates = self.duplicates.saturating_add(1);
            }
            Some(last) => {
                let gap = now.saturating_sub(slot(&geometry, last)).saturating_sub(1);
                self.skipped = self.skipped.saturating_add(gap);
                report.skipped_azimuths += gap;
            }
            // The first azimuth (after start-up or a flush): the rotation is whole from
            // here only if it starts at slot 0.
            None => self.started_at_wrap = now == 0,
        }
        if let Some(last) = self.last_sweep {
            let expected = last.wrapping_add(1);
            if azimuth.sweep_counter != expected {
                let missing = u32::from(azimuth.sweep_counter.wrapping_sub(expected));
                self.sweep_gaps = self.sweep_gaps.saturating_add(1);
                self.sweep_missing = self.sweep_missing.saturating_add(missing);
                report.sweep_missing = missing;
            }
        }
        self.last_sweep = Some(azimuth.sweep_counter);
        self.last_encoder = Some(azimuth.encoder);
        let limit = MAX_ROTATION_FACTOR * usize::from(geometry.azimuth_samples).max(1);
        if self.in_rotation >= limit {
            // The encoder has not wrapped in twice a rotation: stuck. Close what is held as
            // partial and start again from this azimuth.
            report.overlong = true;
            let overlong = self.close(false);
            report.finished = report.finished.or(overlong);
            self.started_at_wrap = false;
        }
        self.in_rotation += 1;
        report.rotation = self.rotation;
        report
    }

    /// Hands out the rotation in progress as partial (shutdown, geometry change).
    pub fn flush(&mut self) -> Option<Rotation> {
        let finished = self.close(false);
        self.started_at_wrap = false;
        self.last_encoder = None;
        finished
    }

    fn close(&mut self, at_wrap: bool) -> Option<Rotation> {
        if self.in_rotation > 0 {
            self.rotation += 1;
        }
        self.in_rotation = 0;
        let geometry = self.geometry.clone();
        let azimuths = std::mem::take(&mut self.current);
        let skipped = std::mem::take(&mut self.skipped);
        let sweep_gaps = std::mem::take(&mut self.sweep_gaps);
        let sweep_missing = std::mem::take(&mut self.sweep_missing);
        let duplicates = std::mem::take(&mut self.duplicates);
        let dropped = std::mem::take(&mut self.dropped);
        let geometry = geometry?;
        if azimuths.is_empty() {
            return None;
        }
        let rotation = Rotation {
            sequence: self.next_sequence,
            azimuths,
            geometry,
            skipped_azimuths: skipped,
            sweep_gaps,
            sweep_missing,
            duplicate_azimuths: duplicates,
            dropped_azimuths: dropped,
            complete: at_wrap && self.started_at_wrap,
        };
        self.next_sequence += 1;
        Some(rotation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytes::Bytes;
    use protocol::BinWidth;

    pub(crate) fn geometry(azimuths: u16, encoder: u16) -> Arc<Geometry> {
        Arc::new(Geometry {
            azimuth_samples: azimuths,
            range_in_bins: 4,
            bin_size_m: 0.25,
            encoder_size: encoder,
            rotation_hz: 4.0,
            packet_rate: azimuths * 4,
            range_gain: 1.0,
            range_offset_m: 0.0,
            data_width: BinWidth::Eight,
            range_resolution_m: None,
        })
    }

    fn az(g: &Arc<Geometry>, slot: u16, sweep: u16) -> Azimuth {
        let encoder = slot * (g.encoder_size / g.azimuth_samples);
        Azimuth {
            encoder,
            angle_rad: g.azimuth_rad(encoder),
            timestamp_s: 1000.0 + f64::from(sweep) * 1e-3,
            sweep_counter: sweep,
            width: BinWidth::Eight,
            bins: Bytes::from_static(&[1, 2, 3, 4]),
            geometry: Arc::clone(g),
            rotation: 0,
        }
    }

    #[test]
    fn a_wrap_hands_out_the_previous_rotation() {
        let g = geometry(8, 80);
        let mut a = RotationAssembler::new();
        a.set_geometry(Arc::clone(&g));
        let mut sweep = 0;
        for s in 3..8 {
            assert!(a.push(az(&g, s, sweep)).finished.is_none());
            sweep += 1;
        }
        let first = a.push(az(&g, 0, sweep)).finished.unwrap();
        sweep += 1;
        assert_eq!(first.sequence, 0);
        assert!(!first.complete, "the first rotation starts mid-way");
        assert_eq!(first.azimuths.len(), 5);
        assert_eq!(first.skipped_azimuths, 0);
        for s in 1..8 {
            assert!(a.push(az(&g, s, sweep)).finished.is_none());
            sweep += 1;
        }
        let second = a.push(az(&g, 0, sweep)).finished.unwrap();
        assert_eq!(second.sequence, 1);
        assert!(second.complete);
        assert_eq!(second.azimuths.len(), 8);
        assert_eq!(
            second
                .azimuths
                .iter()
                .map(|a| a.encoder)
                .collect::<Vec<_>>(),
            vec![0, 10, 20, 30, 40, 50, 60, 70]
        );
        assert_eq!((second.skipped_azimuths, second.sweep_gaps), (0, 0));
    }

    #[test]
    fn skipped_slots_are_counted_inside_and_at_both_ends() {
        let g = geometry(8, 80);
        let mut a = RotationAssembler::new();
        a.set_geometry(Arc::clone(&g));
        a.push(az(&g, 7, 0));
        // Rotation starting at slot 1 (slot 0 missing), slots 3 and 4 missing, ends at 6.
        let r = a.push(az(&g, 1, 1));
        assert_eq!(r.skipped_azimuths, 1);
        assert_eq!(a.push(az(&g, 2, 2)).skipped_azimuths, 0);
        assert_eq!(a.push(az(&g, 5, 3)).skipped_azimuths, 2);
        a.push(az(&g, 6, 4));
        let done = a.push(az(&g, 0, 5));
        assert_eq!(done.skipped_azimuths, 1, "slot 7 missing at the end");
        let rot = done.finished.unwrap();
        assert_eq!(rot.skipped_azimuths, 4);
        assert_eq!(rot.sweep_gaps, 0);
    }

    #[test]
    fn sweep_counter_gaps_are_counted_modulo_two_to_the_sixteen() {
        let g = geometry(8, 80);
        let mut a = RotationAssembler::new();
        a.set_geometry(Arc::clone(&g));
        a.push(az(&g, 1, 65_534));
        assert_eq!(a.push(az(&g, 2, 65_535)).sweep_missing, 0);
        assert_eq!(a.push(az(&g, 3, 0)).sweep_missing, 0, "65535 wraps to 0");
        assert_eq!(a.push(az(&g, 4, 3)).sweep_missing, 2);
        let rot = a.flush().unwrap();
        assert_eq!((rot.sweep_gaps, rot.sweep_missing), (1, 2));
        assert!(!rot.complete);
    }

    #[test]
    fn a_changed_geometry_closes_the_rotation_in_progress() {
        let g1 = geometry(8, 80);
        let g2 = geometry(4, 80);
        let mut a = RotationAssembler::new();
        a.set_geometry(Arc::clone(&g1));
        a.push(az(&g1, 1, 0));
        a.push(az(&g1, 2, 1));
        // The same values again: nothing happens.
        assert!(a.set_geometry(geometry(8, 80)).is_none());
        let closed = a.set_geometry(Arc::clone(&g2)).unwrap();
        assert_eq!(closed.azimuths.len(), 2);
        assert!(!closed.complete);
        assert_eq!(a.pending(), 0);
        // An azimuth with yet another geometry closes the rotation in progress itself.
        a.push(az(&g2, 1, 2));
        let report = a.push(az(&g1, 3, 3));
        assert_eq!(report.finished.unwrap().geometry, g2);
    }

    #[test]
    fn a_first_rotation_starting_at_slot_zero_is_complete() {
        let g = geometry(4, 40);
        let mut a = RotationAssembler::new();
        for s in 0..4 {
            a.push(az(&g, s, s));
        }
        let rot = a.push(az(&g, 0, 4)).finished.unwrap();
        assert!(rot.complete);
        assert_eq!(rot.azimuths.len(), 4);
    }

    #[test]
    fn a_repeated_encoder_value_is_a_duplicate_not_a_new_rotation() {
        let g = geometry(8, 80);
        let mut a = RotationAssembler::new();
        a.push(az(&g, 2, 0));
        assert!(a.push(az(&g, 2, 1)).finished.is_none());
        let rot = a.flush().unwrap();
        assert_eq!(rot.duplicate_azimuths, 1);
        assert_eq!(rot.azimuths.len(), 2);
    }

    proptest::proptest! {
        #[test]
        fn rotations_hold_every_azimuth_once_in_encoder_order(
            steps in proptest::collection::vec((0u16..16, 0u16..3), 1..300)
        ) {
            let g = geometry(16, 160);
            let mut a = RotationAssembler::new();
            let mut pushed = 0usize;
            let mut out = Vec::new();
            let mut slot = 0u16;
            let mut sweep = 0u16;
            for (jump, sweep_step) in steps {
                // Mostly forward, sometimes back (a wrap), with skips.
                slot = (slot + jump) % 16;
                sweep = sweep.wrapping_add(sweep_step);
                out.extend(a.push(az(&g, slot, sweep)).finished);
                pushed += 1;
            }
            out.extend(a.flush());
            let total: usize = out.iter().map(|r| r.azimuths.len()).sum();
            proptest::prop_assert_eq!(total, pushed);
            for (i, r) in out.iter().enumerate() {
                proptest::prop_assert_eq!(r.sequence, i as u64);
                proptest::prop_assert!(r.azimuths.windows(2).all(|w| w[1].encoder >= w[0].encoder));
                if r.complete {
                    let distinct = r.azimuths.len() as u32 - r.duplicate_azimuths;
                    proptest::prop_assert_eq!(distinct + r.skipped_azimuths, 16);
                }
            }
        }
    }

    #[test]
    fn a_stuck_encoder_never_holds_more_than_twice_a_rotation() {
        let g = geometry(16, 64);
        let mut a = RotationAssembler::new();
        let mut closed = 0;
        for sweep in 0..1000u16 {
            // Valid frames whose encoder never decreases: stuck at slot 5.
            let report = a.push(az(&g, 5, sweep));
            assert!(a.pending() <= MAX_ROTATION_FACTOR * 16, "{}", a.pending());
            if report.overlong {
                closed += 1;
                assert!(report.finished.is_some_and(|r| !r.complete));
            }
        }
        assert!(
            closed >= 1000 / 32 - 1,
            "{closed} overlong rotations closed"
        );
    }

    #[test]
    fn every_azimuth_carries_the_number_of_its_rotation() {
        let g = geometry(4, 16);
        let mut a = RotationAssembler::new();
        let numbers: Vec<u64> = [0u16, 1, 2, 3, 0, 1, 2, 3, 0]
            .into_iter()
            .enumerate()
            .map(|(sweep, slot)| a.push(az(&g, slot, u16::try_from(sweep).unwrap())).rotation)
            .collect();
        assert_eq!(numbers, vec![0, 0, 0, 0, 1, 1, 1, 1, 2]);
        // Counting only, the numbers are the same.
        let mut c = RotationAssembler::new();
        c.set_counting_only(true);
        let counted: Vec<u64> = [0u16, 1, 2, 3, 0, 1]
            .into_iter()
            .enumerate()
            .map(|(sweep, slot)| c.push(az(&g, slot, u16::try_from(sweep).unwrap())).rotation)
            .collect();
        assert_eq!(counted, vec![0, 0, 0, 0, 1, 1]);
    }

    #[test]
    fn counting_only_holds_no_azimuth_but_still_counts_skips() {
        let g = geometry(16, 64);
        let mut a = RotationAssembler::new();
        a.set_counting_only(true);
        let mut skipped = 0;
        for (sweep, slot) in [0u16, 1, 2, 5, 6].into_iter().enumerate() {
            let report = a.push(az(&g, slot, u16::try_from(sweep).unwrap()));
            skipped += report.skipped_azimuths;
            assert!(report.finished.is_none());
        }
        assert_eq!(a.pending(), 0);
        assert_eq!(skipped, 2);
    }
}
