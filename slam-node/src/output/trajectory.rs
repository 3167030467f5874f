//! Trajectory in the TUM format: `timestamp x y z qx qy qz qw`, one pose a line, space
//! separated, `#` comment lines allowed. The vehicle moves in the plane: z = 0 and the
//! quaternion is a rotation by theta about +z.

use std::io::{self, Write};

use serde::{Deserialize, Serialize};

/// One estimated (or true) pose with its marginal covariance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseSample {
    /// Unix seconds.
    pub timestamp_s: f64,
    /// East, metres.
    pub x_m: f64,
    /// North, metres.
    pub y_m: f64,
    /// Heading, counter-clockwise from +x, radians.
    pub theta_rad: f64,
    /// Pose covariance, row-major 3x3 over (x, y, theta).
    pub covariance: [[f64; 3]; 3],
}

/// Writes TUM lines to any sink.
#[derive(Debug)]
pub struct TumWriter<W: Write> {
    sink: W,
}

impl<W: Write> TumWriter<W> {
    /// Writes the header comment.
    pub fn new(mut sink: W) -> io::Result<Self> {
        writeln!(sink, "# timestamp x y z qx qy qz qw")?;
        Ok(Self { sink })
    }

    /// Appends one pose.
    pub fn write(&mut self, pose: &PoseSample) -> io::Result<()> {
        let half = 0.5 * pose.theta_rad;
        writeln!(
            self.sink,
            "{:.9} {:.6} {:.6} 0 0 0 {:.9} {:.9}",
            pose.timestamp_s,
            pose.x_m,
            pose.y_m,
            half.sin(),
            half.cos()
        )
    }

    /// Flushes the sink.
    pub fn flush(&mut self) -> io::Result<()> {
        self.sink.flush()
    }
}

/// Reads `(timestamp, x, y, theta)` back from a TUM line (theta from the z-rotation).
pub fn parse_tum_line(line: &str) -> Option<(f64, f64, f64, f64)> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return None;
    }
    let v: Vec<f64> = line
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .ok()?;
    match v.as_slice() {
        [t, x, y, _z, _qx, _qy, qz, qw] => Some((*t, *x, *y, 2.0 * qz.atan2(*qw))),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_pose_reads_back_with_its_heading() {
        let mut buf = Vec::new();
        let mut w = TumWriter::new(&mut buf).unwrap();
        w.write(&PoseSample {
            timestamp_s: 1_700_000_000.25,
            x_m: 1.5,
            y_m: -2.0,
            theta_rad: 2.5,
            covariance: [[0.0; 3]; 3],
        })
        .unwrap();
        let text = String::from_utf8(buf).unwrap();
        let line = text.lines().nth(1).unwrap();
        assert_eq!(line.split(' ').count(), 8);
        let (t, x, y, th) = parse_tum_line(line).unwrap();
        assert!((t - 1_700_000_000.25).abs() < 1e-6);
        assert!((x - 1.5).abs() < 1e-9 && (y + 2.0).abs() < 1e-9);
        assert!((th - 2.5).abs() < 1e-8);
    }
}
