//! Socket options and connecting, in one place.
//!
//! The options (TCP_NODELAY, TCP keep-alive, receive buffer size) are set with `socket2`
//! on the socket before it connects, so the receive buffer can influence the TCP window
//! the radar sees from the first byte; the connect itself runs on tokio under the
//! configured timeout.

use socket2::{Domain, Protocol, SockRef, Socket, TcpKeepalive, Type};
use std::io;
use std::net::SocketAddr;
use std::time::Duration;
use tokio::net::{TcpSocket, TcpStream};

use crate::error::SessionError;

/// Socket options for the radar (and odometry) connections.
#[derive(Debug, Clone, PartialEq)]
pub struct SocketOptions {
    /// Give up a connection attempt after this long.
    pub connect_timeout: Duration,
    /// Disable Nagle's algorithm (matters for the few commands the client sends).
    pub tcp_nodelay: bool,
    /// TCP keep-alive idle time; `None` leaves keep-alive off.
    pub tcp_keepalive: Option<Duration>,
    /// Requested socket receive buffer (the OS may grant a different size).
    pub recv_buffer_bytes: Option<usize>,
}

impl Default for SocketOptions {
    fn default() -> Self {
        Self {
            connect_timeout: Duration::from_millis(3000),
            tcp_nodelay: true,
            tcp_keepalive: None,
            recv_buffer_bytes: Some(4 << 20),
        }
    }
}

/// Applies every option to `socket`. The receive buffer is set before connecting.
pub fn apply_options(socket: &SockRef<'_>, options: &SocketOptions) -> io::Result<()> {
    socket.set_nodelay(options.tcp_nodelay)?;
    if let Some(idle) = options.tcp_keepalive {
        // Probe every idle/3 (at least 1 s) after the idle time: Linux's defaults scaled down.
        let interval = (idle / 3).max(Duration::from_secs(1));
        let keepalive = TcpKeepalive::new().with_time(idle).with_interval(interval);
        socket.set_tcp_keepalive(&keepalive)?;
    }
    if let Some(bytes) = options.recv_buffer_bytes {
        socket.set_recv_buffer_size(bytes)?;
    }
    Ok(())
}

/// Connects to `addr` with `options`, under `options.connect_timeout`.
pub async fn connect(addr: SocketAddr, options: &SocketOptions) -> Result<TcpStream, SessionError> {
    let socket = Socket::new(Domain::for_address(addr), Type::STREAM, Some(Protocol::TCP))
        .map_err(SessionError::SocketOption)?;
    apply_options(&SockRef::from(&socket), options).map_err(SessionError::SocketOption)?;
    socket
        .set_nonblocking(true)
        .map_err(SessionError::SocketOption)?;
    let socket = TcpSocket::from_std_stream(std::net::TcpStream::from(socket));
    match tokio::time::timeout(options.connect_timeout, socket.connect(addr)).await {
        Ok(Ok(stream)) => Ok(stream),
        Ok(Err(source)) => Err(SessionError::Connect { addr, source }),
        Err(_) => Err(SessionError::ConnectTimeout {
            addr,
            timeout: options.connect_timeout,
        }),
    }
}

/// The receive buffer size the OS actually granted (Linux reports double the request).
pub fn granted_recv_buffer(stream: &TcpStream) -> io::Result<usize> {
    SockRef::from(stream).recv_buffer_size()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn options_are_applied_to_a_loopback_connection() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let options = SocketOptions {
            connect_timeout: Duration::from_secs(2),
            tcp_nodelay: true,
            tcp_keepalive: Some(Duration::from_secs(5)),
            recv_buffer_bytes: Some(256 * 1024),
        };
        let (stream, accepted) = tokio::join!(connect(addr, &options), listener.accept());
        let stream = stream.unwrap();
        accepted.unwrap();
        let sock = SockRef::from(&stream);
        assert!(sock.nodelay().unwrap());
        assert!(sock.keepalive().unwrap());
        assert!(granted_recv_buffer(&stream).unwrap() >= 128 * 1024);
    }

    #[tokio::test]
    async fn a_refused_connection_is_a_typed_error() {
        // Bind then drop, so the port is (almost certainly) closed.
        let addr = {
            let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
            l.local_addr().unwrap()
        };
        let err = connect(addr, &SocketOptions::default()).await.unwrap_err();
        assert!(matches!(err, SessionError::Connect { .. }), "{err}");
    }
}
