//! The gyro over TCP: a tokio task keeps the connection (reconnecting with backoff, as the
//! odometry's does) and hands samples to the synchronous [`GyroSource`] side through a
//! bounded channel.

use std::net::SocketAddr;
use std::time::Duration;

use crossbeam_channel::{bounded, Receiver, RecvTimeoutError, Sender, TryRecvError, TrySendError};
use radar_driver::backoff::{Backoff, BackoffPolicy};
use radar_driver::liveness::{bytes_waiting, resume_grace};
use radar_driver::odometry::LineSplitter;
use radar_driver::socket::{connect, SocketOptions};
use radar_driver::Shutdown;
use tokio::io::AsyncReadExt;
use tokio::runtime::Handle;
use tokio::task::JoinHandle;

use super::{GyroError, GyroLineError, GyroParser, GyroPoll, GyroSample, GyroSource};

/// Where and how to read the gyro stream.
#[derive(Debug, Clone, PartialEq)]
pub struct TcpGyroSettings {
    /// The gyro server.
    pub address: SocketAddr,
    /// Socket options and connect timeout.
    pub socket: SocketOptions,
    /// Reconnection delays.
    pub backoff: BackoffPolicy,
    /// Nothing received for this long is a dead link: reconnect.
    pub idle_timeout: Duration,
    /// Samples (and line errors) buffered for the reader; beyond it the newest is dropped.
    pub capacity: usize,
}

impl TcpGyroSettings {
    /// Defaults for `address`: the odometry's socket options, 7 s idle timeout, 4096
    /// samples buffered (40 s at 100 Hz).
    pub fn new(address: SocketAddr) -> Self {
        Self {
            address,
            socket: SocketOptions {
                recv_buffer_bytes: None,
                ..SocketOptions::default()
            },
            backoff: BackoffPolicy::default(),
            idle_timeout: Duration::from_secs(7),
            capacity: 4096,
        }
    }
}

type Item = Result<GyroSample, GyroError>;

/// The reading end of a TCP gyro stream.
#[derive(Debug)]
pub struct TcpGyro {
    rx: Receiver<Item>,
    task: JoinHandle<()>,
}

impl TcpGyro {
    /// Starts the connection task on `runtime`; it runs until `shutdown` fires or this value
    /// is dropped.
    pub fn spawn(runtime: &Handle, settings: TcpGyroSettings, shutdown: Shutdown) -> Self {
        let (tx, rx) = bounded(settings.capacity.max(1));
        let task = runtime.spawn(run(settings, tx, shutdown));
        Self { rx, task }
    }
}

impl Drop for TcpGyro {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl GyroSource for TcpGyro {
    fn poll_next(&mut self, timeout: Duration) -> Result<GyroPoll, GyroError> {
        let got = if timeout.is_zero() {
            self.rx.try_recv().map_err(|e| match e {
                TryRecvError::Empty => RecvTimeoutError::Timeout,
                TryRecvError::Disconnected => RecvTimeoutError::Disconnected,
            })
        } else {
            self.rx.recv_timeout(timeout)
        };
        match got {
            Ok(Ok(s)) => Ok(GyroPoll::Sample(s)),
            Ok(Err(e)) => Err(e),
            Err(RecvTimeoutError::Timeout) => Ok(GyroPoll::Pending),
            Err(RecvTimeoutError::Disconnected) => Ok(GyroPoll::Ended),
        }
    }
}

/// Offers an item; false when the reader is gone. A full channel drops the item.
fn offer(tx: &Sender<Item>, item: Item) -> bool {
    !matches!(tx.try_send(item), Err(TrySendError::Disconnected(_)))
}

async fn run(settings: TcpGyroSettings, tx: Sender<Item>, mut shutdown: Shutdown) {
    let mut backoff = Backoff::new(settings.backoff);
    let mut splitter = LineSplitter::new();
    let mut parser = GyroParser::new();
    loop {
        let connected = tokio::select! {
            c = connect(settings.address, &settings.socket) => c,
            () = shutdown.triggered() => return,
        };
        let mut stream = match connected {
            Ok(s) => s,
            Err(e) => {
                let delay = backoff.next_delay();
                tracing::warn!(address = %settings.address, attempt = backoff.attempt(), ?delay, error = %e, "gyro connection failed; retrying");
                tokio::select! {
                    () = tokio::time::sleep(delay) => continue,
                    () = shutdown.triggered() => return,
                }
            }
        };
        tracing::info!(address = %settings.address, "gyro connected");
        backoff.reset();
        splitter.reset();
        parser.reset();
        let mut line_no = 0u64;
        let mut buf = vec![0u8; 4096];
        let idle = settings.idle_timeout;
        let mut idle_deadline = tokio::time::Instant::now() + idle;
        let end = loop {
            let read = tokio::select! {
                r = tokio::time::timeout_at(idle_deadline, stream.read(&mut buf)) => r,
                () = shutdown.triggered() => return,
            };
            let read = match read {
                Err(_) if bytes_waiting(&stream) => Ok(stream.read(&mut buf).await),
                Err(elapsed) => match resume_grace(idle_deadline, idle) {
                    Some(grace) => {
                        idle_deadline = tokio::time::Instant::now() + grace;
                        continue;
                    }
                    None => Err(elapsed),
                },
                ok => ok,
            };
            let n = match read {
                Ok(Ok(0)) => break "closed by the server".to_owned(),
                Ok(Ok(n)) => {
                    idle_deadline = tokio::time::Instant::now() + idle;
                    n
                }
                Ok(Err(e)) => break format!("read failed: {e}"),
                Err(_) => break format!("nothing received for {idle:?}"),
            };
            splitter.push(buf.get(..n).unwrap_or_default());
            while let Some(line) = splitter.next_line() {
                line_no += 1;
                let item = match line
                    .map_err(GyroLineError::from)
                    .and_then(|l| parser.parse(&l))
                {
                    Ok(Some(sample)) => Ok(sample),
                    Ok(None) => continue,
                    Err(source) => Err(GyroError::Line {
                        line: line_no,
                        source,
                    }),
                };
                if !offer(&tx, item) {
                    return; // The reader is gone.
                }
            }
        };
        let delay = backoff.next_delay();
        tracing::warn!(address = %settings.address, reason = %end, ?delay, "gyro link lost; reconnecting");
        tokio::select! {
            () = tokio::time::sleep(delay) => {}
            () = shutdown.triggered() => return,
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
        let mut gyro = TcpGyro::spawn(rt.handle(), TcpGyroSettings::new(addr), shutdown);
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
