//! Encode and decode throughput of the generated Rust codecs against lcm-gen's C code, side by
//! side in one process: a small message (stride.imu_t), a joint trajectory (12 joints x 500
//! PVT rows) and a 300 000-point cloud. C and Rust batches alternate; the figures are medians.
//!
//! `cargo bench -p stride-tests --bench codec [-- --rounds N]` (scripts/bench codec).

use std::hint::black_box;
use std::time::Instant;

use lcm::Message;
use stride_lcmtypes::stride::{HeaderT, ImuT, JointTrajectoryT, PointCloudT};
use stride_tests as _;

extern "C" {
    fn c_bench_encode_stride_imu_t(i: *const u8, l: i32, n: i32, o: *mut u8) -> i64;
    fn c_bench_decode_stride_imu_t(i: *const u8, l: i32, n: i32) -> i64;
    fn c_bench_encode_stride_joint_trajectory_t(i: *const u8, l: i32, n: i32, o: *mut u8) -> i64;
    fn c_bench_decode_stride_joint_trajectory_t(i: *const u8, l: i32, n: i32) -> i64;
    fn c_bench_encode_stride_point_cloud_t(i: *const u8, l: i32, n: i32, o: *mut u8) -> i64;
    fn c_bench_decode_stride_point_cloud_t(i: *const u8, l: i32, n: i32) -> i64;
}

type CEncode = unsafe extern "C" fn(*const u8, i32, i32, *mut u8) -> i64;
/// One benchmark case: runs its rounds and returns the message size and the figures.
type Case = Box<dyn Fn(usize) -> (usize, Figures, Figures)>;
type CDecode = unsafe extern "C" fn(*const u8, i32, i32) -> i64;

fn header() -> HeaderT {
    HeaderT {
        utime: 1_700_000_000_000_000,
        sequence: 42,
        frame: "pelvis".into(),
    }
}

fn imu() -> ImuT {
    ImuT {
        header: header(),
        orientation: [1.0, 0.0, 0.0, 0.0],
        angular_velocity: [0.01, -0.02, 0.03],
        linear_acceleration: [0.1, 0.2, 9.81],
        temperature: 31.5,
    }
}

fn trajectory() -> JointTrajectoryT {
    let joints = 12;
    let rows = 500;
    JointTrajectoryT {
        header: header(),
        start_utime: 0,
        mode: JointTrajectoryT::MODE_PVT,
        queue: JointTrajectoryT::QUEUE_REPLACE,
        num_joints: joints,
        joint_names: (0..joints).map(|j| format!("leg_joint_{j}")).collect(),
        num_rows: rows,
        time_from_start: (0..rows).map(|r| r as f64 * 0.01).collect(),
        positions: (0..rows)
            .map(|r| (0..joints).map(|j| (r * j) as f64 * 1e-3).collect())
            .collect(),
        velocities: (0..rows)
            .map(|r| (0..joints).map(|j| (r + j) as f64 * 1e-3).collect())
            .collect(),
    }
}

fn cloud() -> PointCloudT {
    let n = 300_000;
    PointCloudT {
        header: header(),
        num_points: n,
        points: (0..n)
            .map(|i| {
                let f = i as f32;
                [f * 0.001, -f * 0.002, 1.0 + f * 1e-6]
            })
            .collect(),
        num_intensities: n,
        intensities: (0..n).map(|i| (i % 256) as f32).collect(),
    }
}

struct Figures {
    c_ns: Vec<f64>,
    rust_ns: Vec<f64>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

fn bench<M: Message>(
    msg: &M,
    iters: i32,
    rounds: usize,
    c_enc: CEncode,
    c_dec: CDecode,
) -> (Figures, Figures) {
    let bytes = msg.encode().unwrap();
    let len = bytes.len() as i32;
    let mut c_out = vec![0u8; bytes.len()];
    let mut buf = Vec::with_capacity(bytes.len());
    let mut enc = Figures {
        c_ns: vec![],
        rust_ns: vec![],
    };
    let mut dec = Figures {
        c_ns: vec![],
        rust_ns: vec![],
    };
    for round in 0..rounds + 1 {
        // SAFETY: the buffers are valid for the lengths passed.
        let c_e = unsafe { c_enc(bytes.as_ptr(), len, iters, c_out.as_mut_ptr()) };
        let t0 = Instant::now();
        for _ in 0..iters {
            buf.clear();
            black_box(msg).encode_into(&mut buf).unwrap();
            black_box(&buf);
        }
        let r_e = t0.elapsed().as_nanos() as f64;
        // SAFETY: as above.
        let c_d = unsafe { c_dec(bytes.as_ptr(), len, iters) };
        let t0 = Instant::now();
        for _ in 0..iters {
            black_box(M::decode(black_box(&bytes)).unwrap());
        }
        let r_d = t0.elapsed().as_nanos() as f64;
        assert!(c_e > 0 && c_d > 0, "the C side failed");
        assert_eq!(buf, bytes);
        assert_eq!(c_out, bytes);
        if round > 0 {
            // Round 0 warms up caches and allocators.
            enc.c_ns.push(c_e as f64 / iters as f64);
            enc.rust_ns.push(r_e / iters as f64);
            dec.c_ns.push(c_d as f64 / iters as f64);
            dec.rust_ns.push(r_d / iters as f64);
        }
    }
    (enc, dec)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds = args
        .iter()
        .position(|a| a == "--rounds")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(15);
    println!("| message | size | operation | C (lcm-gen) | Rust (stride-lcmgen) | Rust / C | bar | verdict |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut fails = 0;
    let mut row = |name: &str, size: usize, op: &str, f: &mut Figures| {
        let c = median(&mut f.c_ns);
        let r = median(&mut f.rust_ns);
        // Throughput ratio: time of C over time of Rust.
        let ratio = c / r;
        let ok = ratio >= 1.0;
        if !ok {
            fails += 1;
        }
        let mbs = |ns: f64| size as f64 / ns * 1e3;
        println!(
            "| {name} | {size} B | {op} | {:.0} MB/s ({:.2} µs) | {:.0} MB/s ({:.2} µs) | {ratio:.2} | ≥ 1.00 | {} |",
            mbs(c),
            c / 1e3,
            mbs(r),
            r / 1e3,
            if ok { "pass" } else { "FAIL" }
        );
    };
    let cases: Vec<(&str, Case)> = vec![
        (
            "small: stride.imu_t",
            Box::new(|rounds| {
                let m = imu();
                let (e, d) = bench(
                    &m,
                    200_000,
                    rounds,
                    c_bench_encode_stride_imu_t,
                    c_bench_decode_stride_imu_t,
                );
                (m.encoded_size(), e, d)
            }),
        ),
        (
            "joint trajectory: 12 joints x 500 PVT rows",
            Box::new(|rounds| {
                let m = trajectory();
                let (e, d) = bench(
                    &m,
                    200,
                    rounds,
                    c_bench_encode_stride_joint_trajectory_t,
                    c_bench_decode_stride_joint_trajectory_t,
                );
                (m.encoded_size(), e, d)
            }),
        ),
        (
            "point cloud: 300 000 points + intensities",
            Box::new(|rounds| {
                let m = cloud();
                let (e, d) = bench(
                    &m,
                    10,
                    rounds,
                    c_bench_encode_stride_point_cloud_t,
                    c_bench_decode_stride_point_cloud_t,
                );
                (m.encoded_size(), e, d)
            }),
        ),
    ];
    for (name, run) in &cases {
        let (size, mut e, mut d) = run(rounds);
        row(name, size, "encode", &mut e);
        row(name, size, "decode", &mut d);
    }
    println!(
        "\n{fails} of {} figures miss the bar (medians of {rounds} rounds).",
        cases.len() * 2
    );
}
