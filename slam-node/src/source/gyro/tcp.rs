//! The gyro over TCP: radar-driver's line-stream client
//! ([`radar_driver::odometry::LineStreamClient`], the odometry's connection, idle timeout
//! and reconnection) with the gyro's parser, behind the synchronous [`GyroSource`] seam.

use std::net::SocketAddr;
use std::time::Duration;

use crossbeam_channel::RecvTimeoutError;
use radar_driver::odometry::{LineStreamClient, LineStreamSettings};
use radar_driver::Shutdown;
use tokio::runtime::Handle;

use super::{GyroError, GyroParser, GyroPoll, GyroSource};

/// Where and how to read the gyro stream.
pub type TcpGyroSettings = LineStreamSettings;

/// Samples buffered by default: 40 s at 100 Hz.
pub const GYRO_CAPACITY: usize = 4096;

/// The gyro's defaults for `address`: the odometry's socket options and 7 s idle timeout,
/// [`GYRO_CAPACITY`] samples buffered.
pub fn tcp_gyro_settings(address: SocketAddr) -> TcpGyroSettings {
    LineStreamSettings {
        capacity: GYRO_CAPACITY,
        ..LineStreamSettings::new(address)
    }
}

/// The reading end of a TCP gyro stream.
#[derive(Debug)]
pub struct TcpGyro {
    client: LineStreamClient<GyroParser>,
}

impl TcpGyro {
    /// Starts the connection task on `runtime`; it runs until `shutdown` fires or this value
    /// is dropped.
    pub fn spawn(runtime: &Handle, settings: TcpGyroSettings, shutdown: Shutdown) -> Self {
        Self {
            client: LineStreamClient::spawn(runtime, settings, GyroParser::new(), shutdown),
        }
    }
}

impl GyroSource for TcpGyro {
    fn poll_next(&mut self, timeout: Duration) -> Result<GyroPoll, GyroError> {
        match self.client.recv(timeout) {
            Ok(Ok(sample)) => Ok(GyroPoll::Sample(sample)),
            Ok(Err(bad)) => Err(GyroError::Line {
                line: bad.line,
                source: bad.error,
            }),
            Err(RecvTimeoutError::Timeout) => Ok(GyroPoll::Pending),
            Err(RecvTimeoutError::Disconnected) => Ok(GyroPoll::Ended),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncWriteExt;

    /// A server on 127.0.0.1:0 writes a header, good and hostile lines; the client hands
    /// back the good samples in order and one error per bad line, in bounded time.
    #[test]
    fn loopback_samples_arrive_and_bad_lines_cost_only_themselves() {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .unwrap();
        let listener = rt
            .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
            .unwrap();
        let addr = listener.local_addr().unwrap();
        rt.spawn(async move {
            let (mut s, _) = listener.accept().await.unwrap();
            let mut text = format!("{}\n1.00 0.10\n1.01 NaN\n", super::super::GYRO_HEADER);
            text.push_str(&"7".repeat(10_000));
            text.push_str("\n1.02 0.20\n");
            s.write_all(text.as_bytes()).await.unwrap();
            tokio::time::sleep(Duration::from_secs(5)).await;
        });
        let (trigger, shutdown) = radar_driver::shutdown_pair();
        let mut gyro = TcpGyro::spawn(rt.handle(), tcp_gyro_settings(addr), shutdown);
        let (mut samples, mut errors) = (Vec::new(), 0);
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while samples.len() < 2 && std::time::Instant::now() < deadline {
            match gyro.poll_next(Duration::from_millis(50)) {
                Ok(GyroPoll::Sample(s)) => samples.push(s.yaw_rate_rad_s),
                Ok(_) => {}
                Err(e) => {
                    assert!(e.is_recoverable());
                    errors += 1;
                }
            }
        }
        assert_eq!(samples, vec![0.1, 0.2]);
        assert_eq!(errors, 2);
        trigger.trigger();
        drop(gyro);
        rt.shutdown_timeout(Duration::from_secs(1));
    }
}
