//! What a client's contour (message 50) and sector blanking (51) do to the azimuths it is
//! sent, as on a radar (`docs/colossus-protocol.md`, sections 2 and 3): a contour value `v`
//! for a degree sends the first `v` bins of its azimuths (bins `0..v`; see `protocol`'s
//! `contour` module for why `v` and not `v + 1`), but only on a contoured stream (started
//! with 21; a non-contoured stream, 140, keeps full-length azimuths); a blanked sector sends
//! azimuths with zero bins. Whether they are the radar's (every client's, outliving the
//! connection) or the connection's own is [`crate::settings::ShapingScope`]. No IO.

use std::sync::{Arc, Mutex, PoisonError};

use bytes::BytesMut;
use protocol::{encode_fft_frame, ContourUpdate, FrameDecoder, Message, SectorBlanking};

/// Why a contour or blanking update was refused (the session goes on without it).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapingError {
    /// A blanking sector's angles are not in [0, 360] degrees.
    #[error("blanking sector {index} ({start_deg} to {end_deg} degrees) is not inside 0 to 360")]
    SectorOutOfRange {
        /// Which sector.
        index: usize,
        /// Its start (degrees).
        start_deg: f64,
        /// Its end (degrees).
        end_deg: f64,
    },
}

/// One client's contour and blanked sectors.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Shaping {
    contour: Option<Box<[u16; 360]>>,
    /// `(start, end)` degrees; a sector whose end is below its start wraps through 0.
    blanked: Vec<(f64, f64)>,
}

impl Shaping {
    /// Takes a contour update (an empty one removes the contour).
    pub fn set_contour(&mut self, update: ContourUpdate) {
        self.contour = match update {
            ContourUpdate::Reset => None,
            ContourUpdate::MaxBinPerDegree(bins) => Some(bins),
        };
    }

    /// Takes a blanking update, replacing the sectors in force; refused whole when any
    /// sector's angles are out of range.
    pub fn set_blanking(&mut self, update: &SectorBlanking) -> Result<(), ShapingError> {
        let mut sectors = Vec::with_capacity(update.sectors.len());
        for (index, s) in update.sectors.iter().enumerate() {
            let (start_deg, end_deg) = (s.start_deg(), s.end_deg());
            let ok = |d: f64| d.is_finite() && (0.0..=360.0).contains(&d);
            if !(ok(start_deg) && ok(end_deg)) {
                return Err(ShapingError::SectorOutOfRange {
                    index,
                    start_deg,
                    end_deg,
                });
            }
            sectors.push((start_deg, end_deg));
        }
        self.blanked = sectors;
        Ok(())
    }

    /// Whether anything is in force.
    pub fn is_active(&self) -> bool {
        self.contour.is_some() || !self.blanked.is_empty()
    }

    fn blanked(&self, deg: f64) -> bool {
        self.blanked.iter().any(|&(a, b)| {
            if a <= b {
                (a..b).contains(&deg)
            } else {
                deg >= a || deg < b
            }
        })
    }

    /// The number of bins to send of an azimuth at `deg` degrees that has `bins` bins, on a
    /// `contoured` stream.
    pub fn bins_to_send(&self, deg: f64, bins: usize, contoured: bool) -> usize {
        if self.blanked(deg) {
            return 0;
        }
        match (&self.contour, contoured) {
            (Some(c), true) => {
                let degree = (deg.floor() as usize).min(359);
                bins.min(usize::from(c[degree]))
            }
            _ => bins,
        }
    }

    /// Applies the shaping to the FFT frame in `frame` (a whole Colossus frame), in place;
    /// `encoder_size` converts its azimuth to degrees. A frame that is not FFT data is left
    /// as it is.
    pub fn apply(&self, frame: &mut BytesMut, encoder_size: u16, contoured: bool) {
        if !self.is_active() || encoder_size == 0 {
            return;
        }
        let mut copy = frame.clone();
        let Ok(Some(Message::FftData(fft))) = FrameDecoder::new().decode_eof(&mut copy) else {
            return;
        };
        let deg = f64::from(fft.azimuth) * 360.0 / f64::from(encoder_size);
        let per_bin = fft.width.bytes_per_bin();
        let keep = self.bins_to_send(deg, fft.bins.len() / per_bin.max(1), contoured);
        if keep * per_bin >= fft.bins.len() {
            return;
        }
        let bins = fft.bins.slice(..keep * per_bin);
        let mut out = BytesMut::with_capacity(frame.len());
        if encode_fft_frame(
            &mut out,
            fft.width,
            fft.sweep_counter,
            fft.azimuth,
            fft.timestamp,
            &bins,
        )
        .is_ok()
        {
            *frame = out;
        }
    }
}

/// The shaping a connection applies: its own, or the radar's, shared by every connection.
#[derive(Debug)]
pub(crate) enum ClientShaping {
    /// The connection's own (it ends with the connection).
    Own(Shaping),
    /// The radar's.
    Shared(Arc<Mutex<Shaping>>),
}

impl ClientShaping {
    /// The radar's shaping when `shared` is set, else a connection's own, empty.
    pub fn new(shared: Option<&Arc<Mutex<Shaping>>>) -> Self {
        shared.map_or_else(
            || Self::Own(Shaping::default()),
            |s| Self::Shared(Arc::clone(s)),
        )
    }

    /// Runs `f` on the shaping in force (a poisoned lock is still the last shaping set).
    pub fn with<R>(&mut self, f: impl FnOnce(&mut Shaping) -> R) -> R {
        match self {
            Self::Own(s) => f(s),
            Self::Shared(s) => f(&mut s.lock().unwrap_or_else(PoisonError::into_inner)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::BlankingSector;

    #[test]
    fn contours_cut_contoured_streams_only_and_blanked_sectors_send_nothing() {
        let mut s = Shaping::default();
        let mut bins = Box::new([1000u16; 360]);
        bins[10] = 99;
        s.set_contour(ContourUpdate::MaxBinPerDegree(bins));
        // v = 99 sends bins 0..99: 99 of them (Navtech's tester sends 100 and counts 100).
        assert_eq!(s.bins_to_send(10.5, 800, true), 99);
        assert_eq!(s.bins_to_send(10.5, 800, false), 800);
        assert_eq!(s.bins_to_send(11.0, 800, true), 800);
        s.set_blanking(&SectorBlanking {
            sectors: vec![BlankingSector::from_degrees(350.0, 20.0)],
        })
        .unwrap();
        assert_eq!(s.bins_to_send(10.5, 800, false), 0);
        assert_eq!(s.bins_to_send(355.0, 800, true), 0);
        assert_eq!(s.bins_to_send(30.0, 800, true), 800);
        let bad = SectorBlanking {
            sectors: vec![BlankingSector::from_degrees(10.0, 400.0)],
        };
        assert!(s.set_blanking(&bad).is_err());
        // The refused update costs nothing: the sectors in force stay.
        assert_eq!(s.bins_to_send(355.0, 800, true), 0);
        s.set_contour(ContourUpdate::Reset);
        s.set_blanking(&SectorBlanking::default()).unwrap();
        assert!(!s.is_active());
    }
}
