//! Slow clients cannot exhaust the server: connections that send part of their headers are
//! closed after the header timeout, a connection cap keeps descriptors for everyone else, and
//! /healthz keeps answering while thousands of half-open connections are held.

mod common;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use common::*;

fn address(s: &Server) -> String {
    s.base.trim_start_matches("http://").to_string()
}

/// The soft limit on open files of this process (the server started from it has the same).
fn open_files_limit() -> Option<usize> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = limits.lines().find(|l| l.starts_with("Max open files"))?;
    line.split_whitespace().nth(3)?.parse().ok()
}

/// A connection that sends the start of a request and never finishes its headers.
fn half_open(addr: &str) -> TcpStream {
    let mut c = TcpStream::connect(addr).unwrap();
    c.write_all(b"GET /healthz HTTP/1.1\r\nHost: millsim\r\n")
        .unwrap();
    c
}

/// A whole /healthz request on a new connection: (status line, time taken).
fn healthz(addr: &str) -> Option<(String, Duration)> {
    let t = Instant::now();
    let mut c = TcpStream::connect(addr).ok()?;
    c.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    c.write_all(b"GET /healthz HTTP/1.1\r\nHost: millsim\r\nConnection: close\r\n\r\n")
        .ok()?;
    let mut out = String::new();
    c.read_to_string(&mut out).ok()?;
    let line = out.lines().next()?.to_string();
    Some((line, t.elapsed()))
}

/// Whether the server closes `c` (end of stream, or a reset) within `within`.
fn closed_within(c: &mut TcpStream, within: Duration) -> bool {
    c.set_read_timeout(Some(within)).unwrap();
    let mut buf = [0u8; 512];
    loop {
        match c.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => continue, // a 408 before closing
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return false,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => return false,
            Err(_) => return true,
        }
    }
}

#[test]
fn thousands_of_half_open_connections_neither_block_healthz_nor_stay_open() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(
        &dir.path().join("t.db"),
        &["--workers", "1", "--header-timeout-s", "2"],
    );
    let addr = address(&s);
    // 5000 where the descriptor limit allows (it does here and in CI); fewer elsewhere.
    let n = open_files_limit().map_or(5000, |l| l.saturating_sub(256).min(5000));
    println!("holding {n} half-open connections");
    let mut held: Vec<TcpStream> = (0..n).map(|_| half_open(&addr)).collect();
    let mut times: Vec<Duration> = (0..7)
        .map(|_| {
            let (line, t) = healthz(&addr).expect("healthz answers");
            assert!(line.contains("200"), "{line}");
            t
        })
        .collect();
    times.sort();
    println!("/healthz with {n} half-open connections: {times:?}");
    assert!(times[3] < Duration::from_millis(100), "{times:?}");
    // After the header timeout every half-open connection is closed by the server.
    let t = Instant::now();
    for c in held.iter_mut().step_by(50) {
        assert!(
            closed_within(c, Duration::from_secs(5)),
            "still open after {:?}",
            t.elapsed()
        );
    }
    assert!(t.elapsed() < Duration::from_secs(5));
}

#[test]
fn over_the_connection_cap_new_connections_are_closed_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(
        &dir.path().join("t.db"),
        &[
            "--workers",
            "1",
            "--header-timeout-s",
            "2",
            "--max-connections",
            "20",
        ],
    );
    let addr = address(&s);
    let held: Vec<TcpStream> = (0..20).map(|_| half_open(&addr)).collect();
    std::thread::sleep(Duration::from_millis(200));
    // The cap is full: the next connection is closed without waiting for its request.
    let mut extra = half_open(&addr);
    assert!(closed_within(&mut extra, Duration::from_secs(1)));
    // The slow ones time out and free their places: the server answers again.
    std::thread::sleep(Duration::from_secs(3));
    let (line, _) = healthz(&addr).expect("healthz answers after the timeout");
    assert!(line.contains("200"), "{line}");
    drop(held);
}
