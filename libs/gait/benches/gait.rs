//! `scripts/bench gait`: the walking pattern's cost and margins, side by side in one run.
//!
//! - one preview-control tick (x and y) at the shipped horizon and at the anchor's (1.6 s),
//!   against the same loop in Python/NumPy when `STRIDE_BENCH_PYTHON` names an interpreter
//!   with NumPy (`libs/gait/benches/preview_numpy.py`);
//! - the COM, ZMP and swing trajectories of a 20-step plan at 200 Hz, by preview control and
//!   by the modified foot placement; Archie's joint trajectories through the legs' IK;
//! - closed-form IK against damped least squares (Archie), and the hexapod leg's closed form;
//! - the smallest ZMP margin of every shipped scene's plan, for both generators.
//!
//! Prints Markdown tables; `--rounds N` sets the repetitions (medians are reported).

#[path = "../tests/common/mod.rs"]
mod common;

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use stride_gait::pattern::{Generator, Kind, Pattern};
use stride_gait::preview::{Cart, Preview, PreviewConfig};
use stride_kinematics::archie::{fk, ik, ik_dls, Leg, Q};
use stride_kinematics::hexapod::{Faithful, Hexapod};
use stride_kinematics::math::Pose;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The median of `rounds` timings of `f`, each divided by `per` (the work it does).
fn median(rounds: usize, per: f64, f: impl FnMut()) -> Duration {
    spread(rounds, per, f).0
}

/// The median and the fastest of `rounds` timings of `f`, each divided by `per`.
fn spread(rounds: usize, per: f64, mut f: impl FnMut()) -> (Duration, Duration) {
    f();
    let mut t: Vec<f64> = (0..rounds)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64() / per
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (
        Duration::from_secs_f64(t[t.len() / 2]),
        Duration::from_secs_f64(t[0]),
    )
}

fn fmt(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 1e-6 {
        format!("{:.0} ns", s * 1e9)
    } else if s < 1e-3 {
        format!("{:.2} µs", s * 1e6)
    } else {
        format!("{:.2} ms", s * 1e3)
    }
}

fn verdict(ok: bool) -> &'static str {
    if ok {
        "holds"
    } else {
        "**fails**"
    }
}

/// A ZMP reference of a walk: x advancing 0.25 m a step, y alternating ±0.1 m, steps of
/// 1.25 s with 0.25 s ramps between, sampled every `dt` for `ticks` ticks plus `pad`.
fn reference(dt: f64, ticks: usize, pad: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for k in 0..ticks + pad {
        let t = (k.min(ticks) as f64) * dt;
        let step = (t / 1.25).floor();
        let within = t - step * 1.25;
        let ramp = ((within - 1.0) / 0.25).clamp(0.0, 1.0);
        let side = |s: f64| if s as i64 % 2 == 0 { 0.1 } else { -0.1 };
        x.push(0.25 * (step + ramp));
        y.push(side(step) * (1.0 - ramp) + side(step + 1.0) * ramp);
    }
    (x, y)
}

/// ns per tick (x and y) of the NumPy loop, when an interpreter with NumPy is given.
fn numpy_tick(horizon: f64, z_c: f64, ticks: usize) -> Option<(f64, String)> {
    let python = std::env::var_os("STRIDE_BENCH_PYTHON")?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/preview_numpy.py");
    let out = Command::new(python)
        .arg(script)
        .args(["--horizon", &horizon.to_string(), "--z-c", &z_c.to_string()])
        .args(["--ticks", &ticks.to_string()])
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let ns = text
        .split_whitespace()
        .find_map(|w| w.strip_prefix("ns_per_tick="))?
        .parse()
        .ok()?;
    let version = text
        .split_whitespace()
        .find_map(|w| w.strip_prefix("numpy="))
        .unwrap_or("?")
        .to_string();
    Some((ns, version))
}

fn preview_ticks(rounds: usize, z_c: f64) -> String {
    let mut out = String::from(
        "| horizon | ticks ahead | Rust, one tick (x and y) | Python/NumPy, same loop | NumPy / Rust | bar: ≤ 1 µs |\n\
         |---|---|---|---|---|---|\n",
    );
    for horizon in [PreviewConfig::default().horizon, 1.6] {
        let cfg = PreviewConfig {
            horizon,
            ..PreviewConfig::default()
        };
        let p = Preview::new(cfg, z_c, 9.80665).unwrap();
        let n = p.horizon_ticks();
        let ticks = 4000;
        let (rx, ry) = reference(cfg.period, ticks, n + 1);
        let t = median(rounds, ticks as f64, || {
            let (mut cx, mut cy) = (Cart::default(), Cart::default());
            for k in 0..ticks {
                p.tick(&mut cx, rx[k], &rx[k + 1..k + 1 + n]);
                p.tick(&mut cy, ry[k], &ry[k + 1..k + 1 + n]);
            }
            black_box((cx, cy));
        });
        let (py, ratio) = match numpy_tick(horizon, z_c, ticks) {
            Some((ns, v)) => (
                format!("{} (NumPy {v})", fmt(Duration::from_secs_f64(ns * 1e-9))),
                format!("{:.0}", ns * 1e-9 / t.as_secs_f64()),
            ),
            None => ("not run (no NumPy)".into(), "–".into()),
        };
        out += &format!(
            "| {horizon} s | {n} | {} | {py} | {ratio} | {} |\n",
            fmt(t),
            verdict(t <= Duration::from_micros(1))
        );
    }
    out
}

fn whole_plan(rounds: usize) -> String {
    let (l, r) = common::standing();
    let steps = common::straight(20, 0.25, 1);
    let archie = common::archie();
    let mut out = String::from(
        "| generator | walk | samples (200 Hz) | COM, ZMP and swings | bar: < 1 ms | Archie's joints with IK (100 Hz rows) | bar: < 5 ms | smallest ZMP margin | footsteps moved off the plan, at most |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    // The third: preview control with Archie's whole body under the pattern, all of it
    // (three patterns and three passes through the legs: no bar of its own); the fourth, as
    // the walker takes a plan.
    let rows = [
        (name(Kind::Preview), generator(Kind::Preview), true, None),
        (
            name(Kind::FootPlacement),
            generator(Kind::FootPlacement),
            true,
            None,
        ),
        (
            "preview control, Archie's whole body (2 passes)",
            common::balanced(Kind::Preview),
            false,
            None,
        ),
        // As the walker takes a plan: it gives way to the next plan (or to its stop) at the
        // third step, and the whole body is put under the pattern up to there.
        (
            "the same, played to the third step's touch-down (as the walker takes a plan)",
            common::balanced(Kind::Preview),
            false,
            Some(3),
        ),
    ];
    for (label, g, barred, played) in rows {
        let start = g.standing(0.0, l, r);
        let pat = match g.plan_until(&start, &steps, played) {
            Ok(p) => p,
            Err(e) => {
                out += &format!("| {label} | refused: {e} | | | | | | | |\n");
                continue;
            }
        };
        let (t, best) = spread(rounds, 1.0, || {
            black_box(g.plan_until(&start, &steps, played).unwrap());
        });
        let joints = match archie.joints(&pat) {
            Ok(_) => {
                let (tj, bj) = spread(rounds, 1.0, || {
                    black_box(archie.joints(&pat).unwrap());
                });
                format!(
                    "{} (fastest {}) | {}",
                    fmt(tj),
                    fmt(bj),
                    verdict(tj < Duration::from_millis(5))
                )
            }
            Err(e) => format!("refused: {e} | –"),
        };
        let bar = if barred {
            verdict(t < Duration::from_millis(1))
        } else {
            "no bar"
        };
        out += &format!(
            "| {label} | 20 steps of 0.25 m, {:.1} s | {} | {} (fastest {}) | {bar} | {joints} | {:.4} m | {:.3} m |\n",
            pat.timeline.end - pat.timeline.start,
            pat.samples.len(),
            fmt(t),
            fmt(best),
            pat.min_margin().0,
            moved(&pat),
        );
    }
    out
}

/// The generators as the benchmark runs them: their defaults.
fn generator(kind: Kind) -> Generator {
    common::generator(kind)
}

/// How far the pattern moved a footstep from its plan, at most, m.
fn moved(p: &Pattern) -> f64 {
    p.placed
        .iter()
        .map(|(f, at)| (at[0] - f.place[0]).hypot(at[1] - f.place[1]))
        .fold(0.0, f64::max)
}

fn name(kind: Kind) -> &'static str {
    match kind {
        Kind::Preview => "preview control",
        Kind::FootPlacement => "modified foot placement",
    }
}

/// Deterministic pseudo-random numbers in [0, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn ik_rates(rounds: usize) -> String {
    let robot = common::robot();
    let links = robot.links;
    let mut rnd = Lcg(7);
    // Reachable soles: FK of joints drawn within the limits, the knee bent.
    let mut targets: Vec<(Leg, Pose, Q)> = Vec::new();
    while targets.len() < 1000 {
        let q: Q = std::array::from_fn(|j| {
            let s = &robot.joint[j];
            let lo = if j == 3 { s.min.max(0.2) } else { s.min };
            lo + (s.max - lo) * rnd.next()
        });
        let leg = if targets.len().is_multiple_of(2) {
            Leg::Left
        } else {
            Leg::Right
        };
        targets.push((leg, fk(&links, leg, &q), q));
    }
    let n = targets.len() as f64;
    let closed = median(rounds, n, || {
        for (leg, pose, _) in &targets {
            black_box(ik(&links, *leg, pose).ok());
        }
    });
    let solved = targets
        .iter()
        .filter(|(leg, pose, _)| ik(&links, *leg, pose).is_ok())
        .count();
    // DLS from the standing pose (as a fallback would start), and from the nearby answer.
    let stand: Q = [0.0, 0.0, -0.6, 1.28, -0.68, 0.0];
    let dls = median(rounds.min(5), n, || {
        for (leg, pose, _) in &targets {
            black_box(ik_dls(&links, *leg, pose, &stand).ok());
        }
    });
    let dls_ok = targets
        .iter()
        .filter(|(leg, pose, _)| ik_dls(&links, *leg, pose, &stand).is_ok())
        .count();
    let near = |q: &Q| -> Q { std::array::from_fn(|j| q[j] + 0.02) };
    let dls_near = median(rounds.min(5), n, || {
        for (leg, pose, q) in &targets {
            black_box(ik_dls(&links, *leg, pose, &near(q)).ok());
        }
    });
    // The hexapod's leg: feet drawn in its working box.
    let hex = Hexapod::load(&root().join("config/robots/hexapod.toml")).unwrap();
    let hl = hex.config().links;
    let feet: Vec<[f64; 3]> = (0..1000)
        .map(|_| {
            [
                0.10 + 0.12 * rnd.next(),
                -0.08 + 0.16 * rnd.next(),
                -0.12 + 0.08 * rnd.next(),
            ]
        })
        .collect();
    let hex_t = median(rounds, feet.len() as f64, || {
        for f in &feet {
            black_box(hl.ik(*f, Faithful::default()).ok());
        }
    });
    let hex_ok = feet
        .iter()
        .filter(|f| hl.ik(**f, Faithful::default()).is_ok())
        .count();
    let rate = |d: Duration| 1.0 / d.as_secs_f64();
    format!(
        "| solver | targets | solved | per solve | solves/s | bar |\n\
         |---|---|---|---|---|---|\n\
         | Archie leg, closed form | {} reachable soles | {solved} | {} | {:.2} M | ≥ 1 M/s: {} |\n\
         | Archie leg, damped least squares from the standing pose | same | {dls_ok} | {} | {:.3} M | closed form {:.0}× faster |\n\
         | Archie leg, damped least squares from 0.02 rad off the answer | same | – | {} | {:.3} M | closed form {:.0}× faster |\n\
         | hexapod leg, closed form | {} feet in its working box | {hex_ok} | {} | {:.2} M | ≥ 5 M/s: {} |\n",
        targets.len(),
        fmt(closed),
        rate(closed) / 1e6,
        verdict(rate(closed) >= 1e6),
        fmt(dls),
        rate(dls) / 1e6,
        dls.as_secs_f64() / closed.as_secs_f64(),
        fmt(dls_near),
        rate(dls_near) / 1e6,
        dls_near.as_secs_f64() / closed.as_secs_f64(),
        feet.len(),
        fmt(hex_t),
        rate(hex_t) / 1e6,
        verdict(rate(hex_t) >= 5e6),
    )
}

fn scene_margins() -> String {
    let gens = [generator(Kind::Preview), generator(Kind::FootPlacement)];
    let mut out = String::from(
        "| scene | steps | preview control: smallest margin | stretched steps | modified foot placement: smallest margin | stretched steps | footsteps moved, at most |\n\
         |---|---|---|---|---|---|---|\n",
    );
    let mut worst = [f64::INFINITY; 2];
    let mut counted = 0;
    for walk in common::scene_walks() {
        let w = match walk {
            Ok(w) => w,
            Err((name, why)) => {
                out += &format!("| {name} | – | no plan ({why}) | – | – | – | – |\n");
                continue;
            }
        };
        let mut cells = Vec::new();
        for (i, g) in gens.iter().enumerate() {
            let start = g.standing(0.0, w.feet.0, w.feet.1);
            match g.plan(&start, &w.steps) {
                Ok(pat) => {
                    let m = pat.min_margin().0;
                    worst[i] = worst[i].min(m);
                    cells.push(format!(
                        "{m:.4} m | {}",
                        common::stretched(g, &pat, &w.steps)
                    ));
                    if i == 1 {
                        cells.push(format!("{:.3} m", moved(&pat)));
                    }
                }
                Err(e) => {
                    cells.push(format!("refused ({e}) | –"));
                    if i == 1 {
                        cells.push("–".into());
                    }
                }
            }
        }
        counted += 1;
        out += &format!(
            "| {} | {} | {} |\n",
            w.name,
            w.steps.len(),
            cells.join(" | ")
        );
    }
    out += &format!(
        "\nSmallest over the {counted} planned scenes: preview control {:.4} m, modified foot \
         placement {:.4} m (bar: ≥ 0.01 m, checked on every pattern; a plan that cannot keep it \
         even with its steps stretched to T_max is refused).\n",
        worst[0], worst[1]
    );
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds = args
        .iter()
        .position(|a| a == "--rounds")
        .and_then(|i| args.get(i + 1))
        .and_then(|r| r.parse().ok())
        .unwrap_or(30usize);
    let z_c = common::z_c();
    println!("### One preview-control tick (COM height {z_c:.3} m, T = 5 ms)\n");
    println!("{}", preview_ticks(rounds, z_c));
    println!("### A 20-step plan, both generators\n");
    println!("{}", whole_plan(rounds));
    println!("### Leg inverse kinematics\n");
    println!("{}", ik_rates(rounds));
    println!("### Every shipped scene's plan walked, both generators\n");
    println!("{}", scene_margins());
}
