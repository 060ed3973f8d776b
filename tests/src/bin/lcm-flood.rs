//! `lcm-flood`: floods a robot's footstep plan channel as a hostile peer would, for the soak
//! test: stale plans (echoing a step long past), plans with NaN footholds for the step under
//! way, byte copies of the planner's last plan, and random bytes, in turn, at a fixed rate.
//! Prints what it sent as one JSON line.

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::Parser;
use lcm::{Lcm, Message};
use stride_lcmtypes::stride::{FootT, FootstepPlanT, FootstepT, HeaderT, StepCounterT};

/// Floods CHANNEL with bad and copied plans.
#[derive(Parser, Debug)]
struct Cli {
    /// LCM URL.
    #[arg(long)]
    lcm_url: String,
    /// The plans' channel.
    #[arg(long, default_value = "FOOTSTEP_PLAN")]
    channel: String,
    /// The gait's step counter (stale and NaN plans echo it).
    #[arg(long, default_value = "STEP_COUNTER")]
    counter: String,
    /// Messages a second.
    #[arg(long, default_value_t = 5000.0)]
    rate: f64,
    /// For how long, s.
    #[arg(long, default_value_t = 3.0)]
    seconds: f64,
}

fn utime() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as i64)
}

/// Three steps from `echo + 1`, the first foothold at `x`.
fn plan(seq: i64, echo: i64, x: f64) -> FootstepPlanT {
    FootstepPlanT {
        header: HeaderT {
            utime: utime(),
            sequence: seq,
            frame: "flood".into(),
        },
        request_id: -1,
        step_number: echo,
        status: FootstepPlanT::STATUS_OK,
        num_steps: 3,
        steps: (0..3)
            .map(|i| FootstepT {
                step_number: echo + 1 + i,
                foot: FootT {
                    side: if i % 2 == 0 {
                        FootT::SIDE_LEFT
                    } else {
                        FootT::SIDE_RIGHT
                    },
                    x,
                    y: if i % 2 == 0 { 0.1 } else { -0.1 },
                    ..Default::default()
                },
                swing_height: 0.03,
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    }
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let lcm = Lcm::new(&cli.lcm_url)?;
    let counter = Arc::new(AtomicI64::new(i64::MIN));
    let c = counter.clone();
    let _counter = lcm.subscribe(&cli.counter, move |_, m: StepCounterT| {
        c.store(m.step_number, Ordering::Relaxed);
    })?;
    // The planner's last plan, as its bytes.
    let copy: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
    let k = copy.clone();
    let _plans = lcm.subscribe_raw(&cli.channel, move |_, data| {
        if let Ok(p) = FootstepPlanT::decode(data) {
            if p.header.frame != "flood" && p.status == FootstepPlanT::STATUS_OK {
                *k.lock().unwrap() = Some(data.to_vec());
            }
        }
    })?;
    let t0 = Instant::now();
    while (counter.load(Ordering::Relaxed) == i64::MIN || copy.lock().unwrap().is_none())
        && t0.elapsed() < Duration::from_secs(60)
    {
        lcm.handle_timeout(Duration::from_millis(50))?;
    }
    let copied = copy
        .lock()
        .unwrap()
        .clone()
        .ok_or_else(|| anyhow::anyhow!("no plan of the planner's to copy within 60 s"))?;
    let n = (cli.rate * cli.seconds).round() as u64;
    let period = Duration::from_secs_f64(1.0 / cli.rate);
    let (mut stale, mut nan, mut copies, mut bytes) = (0u64, 0u64, 0u64, 0u64);
    let mut seq = 0i64;
    let mut rng = 0x9e37_79b9_7f4a_7c15u64 ^ utime() as u64;
    let start_utime = utime();
    let start = Instant::now();
    for i in 0..n {
        let due = start + period * i as u32;
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        if i % 64 == 0 {
            while lcm.handle_timeout(Duration::ZERO)? {}
        }
        let echo = counter.load(Ordering::Relaxed);
        match i % 4 {
            0 => {
                seq += 1;
                lcm.publish(&cli.channel, &plan(seq, echo - 5, 0.1))?;
                stale += 1;
            }
            1 => {
                seq += 1;
                lcm.publish(&cli.channel, &plan(seq, echo, f64::NAN))?;
                nan += 1;
            }
            2 => {
                lcm.publish_raw(&cli.channel, &copied)?;
                copies += 1;
            }
            _ => {
                let junk: Vec<u8> = (0..200)
                    .map(|_| {
                        rng ^= rng << 13;
                        rng ^= rng >> 7;
                        rng ^= rng << 17;
                        rng as u8
                    })
                    .collect();
                lcm.publish_raw(&cli.channel, &junk)?;
                bytes += 1;
            }
        }
    }
    println!(
        "{{\"sent\": {n}, \"stale\": {stale}, \"nan\": {nan}, \"copy\": {copies}, \"bytes\": {bytes}, \"start_utime\": {start_utime}, \"end_utime\": {}}}",
        utime()
    );
    Ok(())
}
