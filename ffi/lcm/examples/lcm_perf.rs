//! `lcm_perf`: the LCM latency and throughput benchmark on the safe `lcm` crate.
//!
//! The same protocol and output as `ffi/lcm/bench/lcm_perf.c` (written directly on liblcm), so
//! `scripts/bench lcm` can compare the two side by side:
//!
//! ```text
//! lcm_perf pong   URL                      echo PERF_PING back on PERF_PONG until killed
//! lcm_perf ping   URL SIZE COUNT           COUNT round trips of SIZE-byte messages
//! lcm_perf sink   URL                      receive PERF_DATA, acknowledge on PERF_ACK
//! lcm_perf source URL SIZE COUNT WINDOW    send COUNT messages, at most WINDOW unacknowledged
//! lcm_perf loop   URL SIZE COUNT           publish and handle COUNT messages in one process
//!                                          (memq://: the library's own cost per message)
//! ```

use std::cell::Cell;
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::Arc;
use std::time::{Duration, Instant};

use lcm::Lcm;

fn get_u64(b: &[u8]) -> u64 {
    u64::from_ne_bytes(b[..8].try_into().unwrap())
}

fn pct(v: &[u64], p: f64) -> u64 {
    if v.is_empty() {
        return 0;
    }
    let rank = ((p / 100.0) * v.len() as f64 + 0.999999) as usize;
    v[rank.clamp(1, v.len()) - 1]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: lcm_perf pong|ping|sink|source URL [SIZE COUNT [WINDOW]]");
        std::process::exit(2);
    }
    let arg = |i: usize| -> u64 { args[i].parse().expect("a number") };
    let lcm = Lcm::new(&args[2]).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    let one_sec = Duration::from_secs(1);
    match args[1].as_str() {
        "pong" => {
            let p = lcm.publisher();
            let s = lcm
                .subscribe_raw("PERF_PING", move |_, data| {
                    let _ = p.publish_raw("PERF_PONG", data);
                })
                .unwrap();
            s.set_queue_capacity(10000).unwrap();
            loop {
                let _ = lcm.handle();
            }
        }
        "sink" => {
            let count = Arc::new(AtomicU64::new(0));
            let ack_every = Arc::new(AtomicU64::new(1));
            let (p, c, a) = (lcm.publisher(), count.clone(), ack_every.clone());
            let s = lcm
                .subscribe_raw("PERF_DATA", move |_, data| {
                    let n = c.fetch_add(1, Relaxed) + 1;
                    let total = if data.len() >= 16 {
                        get_u64(&data[8..])
                    } else {
                        0
                    };
                    if n % a.load(Relaxed) == 0 || n == total {
                        let _ = p.publish_raw("PERF_ACK", &n.to_ne_bytes());
                    }
                })
                .unwrap();
            s.set_queue_capacity(0).unwrap();
            let p = lcm.publisher();
            let _r = lcm
                .subscribe_raw("PERF_RESET", move |_, data| {
                    count.store(0, Relaxed);
                    let every = if data.len() >= 8 { get_u64(data) } else { 1 };
                    ack_every.store(every.max(1), Relaxed);
                    let _ = p.publish_raw("PERF_ACK", &0u64.to_ne_bytes());
                })
                .unwrap();
            loop {
                let _ = lcm.handle();
            }
        }
        "ping" if args.len() >= 5 => {
            let size = (arg(3) as usize).max(8);
            let count = arg(4) as usize;
            let mut buf = vec![0u8; size];
            let want = Arc::new(AtomicU64::new(0));
            let got = Arc::new(AtomicU64::new(0));
            let (w, g) = (want.clone(), got.clone());
            let _s = lcm
                .subscribe_raw("PERF_PONG", move |_, data| {
                    if data.len() >= 8 && get_u64(data) == w.load(Relaxed) {
                        g.store(1, Relaxed);
                    }
                })
                .unwrap();
            // Warm up until the pong answers (it may still be starting).
            let mut warm = 0;
            for tries in 0..200u64 {
                if warm >= 50 {
                    break;
                }
                want.store(1 << 62 | tries, Relaxed);
                got.store(0, Relaxed);
                buf[..8].copy_from_slice(&want.load(Relaxed).to_ne_bytes());
                lcm.publish_raw("PERF_PING", &buf).unwrap();
                while got.load(Relaxed) == 0
                    && lcm.handle_timeout(Duration::from_millis(100)).unwrap()
                {}
                if got.load(Relaxed) == 1 {
                    warm += 1;
                }
            }
            let mut rtt = Vec::with_capacity(count);
            let mut lost = 0;
            for i in 0..count as u64 {
                want.store(i, Relaxed);
                got.store(0, Relaxed);
                buf[..8].copy_from_slice(&i.to_ne_bytes());
                let t0 = Instant::now();
                lcm.publish_raw("PERF_PING", &buf).unwrap();
                while got.load(Relaxed) == 0 {
                    if !lcm.handle_timeout(one_sec).unwrap_or(false) {
                        break;
                    }
                }
                if got.load(Relaxed) == 1 {
                    rtt.push(t0.elapsed().as_nanos() as u64);
                } else {
                    lost += 1;
                }
            }
            rtt.sort_unstable();
            let mean = rtt.iter().sum::<u64>() as f64 / rtt.len().max(1) as f64;
            println!(
                "impl=rust mode=latency size={size} count={count} lost={lost} p50_us={:.2} p90_us={:.2} p99_us={:.2} mean_us={:.2} rtt_ns={}",
                pct(&rtt, 50.0) as f64 / 1e3,
                pct(&rtt, 90.0) as f64 / 1e3,
                pct(&rtt, 99.0) as f64 / 1e3,
                mean / 1e3,
                // Every round trip, sorted, so that percentiles can be pooled over runs.
                rtt.iter().map(u64::to_string).collect::<Vec<_>>().join(",")
            );
        }
        "source" if args.len() >= 6 => {
            let size = (arg(3) as usize).max(16);
            let count = arg(4);
            let window = arg(5).max(1);
            let ack_every = (window / 2).max(1);
            let mut buf = vec![0u8; size];
            let acked = Rc::new(Cell::new(0u64));
            let seen = Arc::new(AtomicU64::new(0));
            let acked_shared = Arc::new(AtomicU64::new(0));
            let (a, s) = (acked_shared.clone(), seen.clone());
            let _sub = lcm
                .subscribe_raw("PERF_ACK", move |_, data| {
                    if data.len() >= 8 {
                        a.store(get_u64(data), Relaxed);
                        s.store(1, Relaxed);
                    }
                })
                .unwrap();
            for _ in 0..100 {
                if seen.load(Relaxed) == 1 {
                    break;
                }
                lcm.publish_raw("PERF_RESET", &ack_every.to_ne_bytes())
                    .unwrap();
                let _ = lcm.handle_timeout(Duration::from_millis(100));
            }
            if seen.load(Relaxed) == 0 {
                eprintln!("no sink answered");
                std::process::exit(1);
            }
            acked_shared.store(0, Relaxed);
            let t0 = Instant::now();
            let mut sent = 0u64;
            loop {
                acked.set(acked_shared.load(Relaxed));
                if acked.get() >= count {
                    break;
                }
                while sent < count && sent - acked.get() < window {
                    buf[..8].copy_from_slice(&sent.to_ne_bytes());
                    buf[8..16].copy_from_slice(&count.to_ne_bytes());
                    lcm.publish_raw("PERF_DATA", &buf).unwrap();
                    sent += 1;
                }
                if !lcm.handle_timeout(one_sec).unwrap_or(false) {
                    break;
                }
            }
            let acked = acked_shared.load(Relaxed);
            let secs = t0.elapsed().as_secs_f64();
            println!(
                "impl=rust mode=throughput size={size} count={count} lost={} msgs_per_s={:.1} mb_per_s={:.2}",
                count - acked,
                acked as f64 / secs,
                acked as f64 * size as f64 / secs / 1e6
            );
        }
        "loop" if args.len() >= 5 => {
            let size = arg(3) as usize;
            let count = arg(4);
            let buf = vec![0u8; size.max(8)];
            let received = Arc::new(AtomicU64::new(0));
            let r = received.clone();
            let _s = lcm
                .subscribe_raw("PERF_DATA", move |_, data| {
                    r.fetch_add(1, Relaxed);
                    std::hint::black_box(data);
                })
                .unwrap();
            for _ in 0..count {
                lcm.publish_raw("PERF_DATA", &buf[..size]).unwrap();
                lcm.handle().unwrap();
            }
            println!(
                "impl=rust mode=loop size={size} count={count} received={}",
                received.load(Relaxed)
            );
        }
        _ => {
            eprintln!("bad arguments");
            std::process::exit(2);
        }
    }
}
