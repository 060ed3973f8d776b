//! `tcpq://` without a server: errors, never an instance that aborts the process later.

use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use lcm::{Error, Lcm};

#[test]
fn an_unreachable_tcpq_server_is_an_error_not_an_abort() {
    let addr: SocketAddr = "127.0.0.1:1".parse().unwrap();
    if TcpStream::connect_timeout(&addr, Duration::from_secs(1)).is_ok() {
        // Inside scripts/test's network namespace nothing else listens: a skip there would
        // hide the test, so it fails instead.
        assert!(
            std::env::var_os("STRIDE_NETNS").is_none(),
            "something listens on {addr} inside the test namespace"
        );
        eprintln!("skipped: something listens on {addr}");
        return;
    }
    let err = Lcm::new("tcpq://127.0.0.1:1").unwrap_err();
    assert!(matches!(err, Error::Connect { .. }), "{err:?}");
    assert_eq!(
        err.to_string(),
        "LCM URL tcpq://127.0.0.1:1: cannot reach the server"
    );
}

/// A server that completes liblcm's tcpq handshake, then hangs up.
fn hang_up_after_handshake() -> (u16, std::thread::JoinHandle<()>) {
    use std::io::{Read, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = std::thread::spawn(move || {
        let (mut conn, _) = listener.accept().unwrap();
        let mut hello = [0u8; 8]; // the client's magic and protocol version
        conn.read_exact(&mut hello).unwrap();
        conn.write_all(&0x2876_17fa_u32.to_be_bytes()).unwrap();
        conn.write_all(&0x0100_u32.to_be_bytes()).unwrap();
    });
    (port, server)
}

#[test]
fn a_broken_tcpq_connection_is_an_error_not_an_abort() {
    let (port, server) = hang_up_after_handshake();
    let lcm = Lcm::new(&format!("tcpq://127.0.0.1:{port}")).unwrap();
    server.join().unwrap();
    assert!(lcm.fileno() >= 0);
    // liblcm reads the end of the stream and closes its socket.
    let _ = lcm.handle_timeout(Duration::from_secs(5));
    assert_eq!(lcm.fileno(), -1);
    let no_fd = |r: lcm::Result<_>| matches!(r, Err(Error::NoDescriptor { .. }));
    assert!(no_fd(lcm.try_fd().map(|_| ())));
    assert!(no_fd(
        lcm.handle_timeout(Duration::from_millis(10)).map(|_| ())
    ));
    assert!(no_fd(lcm.handle_pending().map(|_| ())));
}
