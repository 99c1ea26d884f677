//! A fake X-Plane that answers dataref subscriptions as X-Plane's UDP interface does
//! (docs/live.md, *X-Plane*): a request is `RREF\0`, the frequency (i32, per second; 0 ends
//! the subscription), the requester's index (i32) and the dataref's path (400 bytes,
//! NUL-padded), little-endian. X-Plane then sends to the address the request came from, once
//! a frame at most and at the asked frequency, `RREF,` and one (index i32, value f32) pair a
//! subscribed dataref, every value as a float whatever the dataref's type (an int dataref's
//! 1 is 1.0). The fake's frames come on the wall clock at a rate of its own, its simulator
//! time counting from the first subscription.

use std::collections::BTreeMap;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the fake saw, for the test's asserts.
#[derive(Debug, Default)]
pub struct XPlaneReport {
    /// Frames sent with at least one value.
    pub frames_sent: usize,
    /// Datarefs asked for that the test's model does not give (X-Plane would know them).
    pub unknown: Vec<String>,
    /// Every dataref subscribed, in the order first asked, with its frequency.
    pub subscribed: Vec<(String, i32)>,
    /// Subscriptions ended with frequency 0.
    pub unsubscribed: usize,
}

pub struct FakeXPlane {
    pub addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<XPlaneReport>>,
}

/// One subscription: the dataref, its frequency, and the share of a send accumulated.
struct Subscription {
    dataref: String,
    freq_hz: i32,
    due: f64,
}

impl FakeXPlane {
    /// Starts the fake on 127.0.0.1 (a free port) with frames at `frame_hz`; `value(t_s,
    /// dataref)` is the dataref's value at simulator time `t_s`, `None` for one it does not
    /// model.
    pub fn start(
        frame_hz: f64,
        value: impl Fn(f64, &str) -> Option<f32> + Send + 'static,
    ) -> FakeXPlane {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket.set_nonblocking(true).unwrap();
        let addr = socket.local_addr().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut report = XPlaneReport::default();
            // Per requesting address, its subscriptions by index.
            let mut subs = Subscriptions::new();
            let mut first: Option<Instant> = None;
            let mut frame: u64 = 0;
            while !stopped.load(Ordering::Relaxed) {
                drain(&socket, &mut subs, &mut report, &mut first);
                let Some(start) = first else {
                    std::thread::sleep(Duration::from_millis(1));
                    continue;
                };
                let t_s = frame as f64 / frame_hz;
                for (to, by_index) in subs.iter_mut() {
                    let mut reply = b"RREF,".to_vec();
                    for (index, s) in by_index.iter_mut() {
                        // At most once a frame, at the asked frequency.
                        s.due += f64::from(s.freq_hz) / frame_hz;
                        if s.due < 1.0 {
                            continue;
                        }
                        s.due = (s.due - 1.0).min(1.0);
                        match value(t_s, &s.dataref) {
                            Some(v) => {
                                reply.extend(index.to_le_bytes());
                                reply.extend(v.to_le_bytes());
                            }
                            None => {
                                if !report.unknown.contains(&s.dataref) {
                                    report.unknown.push(s.dataref.clone());
                                }
                            }
                        }
                    }
                    if reply.len() > 5 {
                        // The session may be gone: a refused send is not the fake's failure.
                        let _ = socket.send_to(&reply, to);
                        report.frames_sent += 1;
                    }
                }
                frame += 1;
                let next = start + Duration::from_secs_f64(frame as f64 / frame_hz);
                std::thread::sleep(next.saturating_duration_since(Instant::now()));
            }
            // What came before the stop (the session's farewell).
            drain(&socket, &mut subs, &mut report, &mut first);
            report
        });
        FakeXPlane {
            addr,
            stop,
            thread: Some(thread),
        }
    }

    /// Stops the frames (and waits for the farewell the session sent before, if any).
    pub fn stop(mut self) -> XPlaneReport {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

impl Drop for FakeXPlane {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

type Subscriptions = BTreeMap<SocketAddr, BTreeMap<i32, Subscription>>;

/// Reads every request waiting, as X-Plane does between frames.
fn drain(
    socket: &UdpSocket,
    subs: &mut Subscriptions,
    report: &mut XPlaneReport,
    first: &mut Option<Instant>,
) {
    let mut buf = [0u8; 2048];
    while let Ok((n, from)) = socket.recv_from(&mut buf) {
        let d = &buf[..n];
        assert!(
            n == 413 && &d[..5] == b"RREF\0",
            "not an RREF request: {n} bytes"
        );
        let freq = i32::from_le_bytes(d[5..9].try_into().unwrap());
        let index = i32::from_le_bytes(d[9..13].try_into().unwrap());
        let path = &d[13..];
        let end = path.iter().position(|b| *b == 0).unwrap_or(path.len());
        let dataref = String::from_utf8(path[..end].to_vec()).unwrap();
        if freq == 0 {
            if let Some(s) = subs.get_mut(&from) {
                report.unsubscribed += usize::from(s.remove(&index).is_some());
            }
            continue;
        }
        if !report.subscribed.iter().any(|(d, _)| *d == dataref) {
            report.subscribed.push((dataref.clone(), freq));
        }
        first.get_or_insert_with(Instant::now);
        subs.entry(from).or_default().insert(
            index,
            Subscription {
                dataref,
                freq_hz: freq,
                due: 1.0,
            },
        );
    }
}
