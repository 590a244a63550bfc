//! A TCP proxy that delays what it forwards (`v2t-bench netdelay`): every chunk read from one side
//! is written to the other a fixed time after it was read, in order, so one connection through it
//! behaves like a link with that one-way delay in each direction (TCP's own order kept; no loss:
//! loss on a TCP link is retransmission, which shows as delay). Put between a BV and the broker,
//! it adds the delay to everything the BV sends and receives.

use std::io::{Read as _, Write as _};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Largest chunk read at once, bytes.
const CHUNK: usize = 64 * 1024;

/// Forwards every connection accepted on `listener` to `upstream`, delaying the client's bytes by
/// `up` and the upstream's by `down`. Runs until the listener fails.
pub fn serve(listener: &TcpListener, upstream: SocketAddr, up: Duration, down: Duration) -> std::io::Result<()> {
    loop {
        let (client, _) = listener.accept()?;
        let server = match TcpStream::connect(upstream) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("netdelay: upstream {upstream}: {e}");
                continue;
            }
        };
        for s in [&client, &server] {
            s.set_nodelay(true)?;
        }
        pump(client.try_clone()?, server.try_clone()?, up);
        pump(server, client, down);
    }
}

/// Copies `from` to `to`, each chunk `delay` after it was read (a reader and a writer thread).
fn pump(mut from: TcpStream, mut to: TcpStream, delay: Duration) {
    let (tx, rx) = mpsc::channel::<(Instant, Vec<u8>)>();
    std::thread::spawn(move || {
        let mut buf = vec![0u8; CHUNK];
        loop {
            match from.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => {
                    if tx.send((Instant::now() + delay, buf.get(..n).unwrap_or_default().to_vec())).is_err() {
                        break;
                    }
                }
            }
        }
    });
    std::thread::spawn(move || {
        while let Ok((due, bytes)) = rx.recv() {
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
            if to.write_all(&bytes).is_err() {
                break;
            }
        }
        let _ = to.shutdown(std::net::Shutdown::Both);
    });
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    /// An echo server behind the proxy answers after both delays, and bytes keep their order.
    #[test]
    fn the_proxy_delays_each_direction_and_keeps_the_order() {
        let echo = TcpListener::bind("127.0.0.1:0").unwrap();
        let echo_addr = echo.local_addr().unwrap();
        std::thread::spawn(move || {
            let (mut s, _) = echo.accept().unwrap();
            let mut buf = [0u8; 256];
            while let Ok(n) = s.read(&mut buf) {
                if n == 0 || s.write_all(&buf[..n]).is_err() {
                    break;
                }
            }
        });
        let proxy = TcpListener::bind("127.0.0.1:0").unwrap();
        let proxy_addr = proxy.local_addr().unwrap();
        std::thread::spawn(move || serve(&proxy, echo_addr, Duration::from_millis(40), Duration::from_millis(60)));
        let mut c = TcpStream::connect(proxy_addr).unwrap();
        c.set_nodelay(true).unwrap();
        let t0 = Instant::now();
        c.write_all(b"abc").unwrap();
        c.write_all(b"def").unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 16];
        while got.len() < 6 {
            let n = c.read(&mut buf).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        let rtt = t0.elapsed();
        assert_eq!(got, b"abcdef");
        assert!(rtt >= Duration::from_millis(100), "round trip {rtt:?} shorter than 40 + 60 ms");
        assert!(rtt < Duration::from_millis(600), "round trip {rtt:?}");
    }
}
