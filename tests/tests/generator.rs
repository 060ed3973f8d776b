//! The generated Rust against golden vectors (from lcm-gen's C output), and decoders against
//! malformed input.

use lcm::{DecodeError, EncodeError, Message, Random, Rng};
use stride_tests::features::demo::{PointT, SampleT};
use stride_tests::features::lcmtest::{KeywordsT, MultidimT, NodeT};
use stride_tests::features::{EmptyT, TinyT};

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn sample() -> SampleT {
    SampleT {
        utime: 0x0102030405060708,
        i8: -1,
        i16: -2,
        i32: 0x11223344,
        f: 1.5,
        d: -2.25,
        name: "hi".into(),
        ok: true,
        raw: [0xde, 0xad, 0xbe, 0xef],
        n: 2,
        blob: vec![0xaa, 0xbb],
        ranges: vec![1.0, 2.0],
        flags: [vec![true, false], vec![false, true]],
        names: vec!["a".into(), String::new()],
        p: PointT { x: 1.0, y: 2.0 },
        pts: vec![PointT { x: 3.0, y: 4.0 }, PointT { x: 5.0, y: 6.0 }],
        grid: core::array::from_fn(|i| {
            core::array::from_fn(|j| PointT {
                x: i as f64,
                y: j as f64,
            })
        }),
    }
}

#[test]
fn sample_matches_lcm_gen_bytes() {
    let mut want = String::from(
        "154a32423e821b710102030405060708fffffe112233443fc00000c002000000000000\
         00000003686900\
         01deadbeef00000002aabb3ff00000000000004000000000000000\
         01000001\
         000000026100\
         0000000100\
         3ff00000000000004000000000000000\
         4008000000000000401000000000000040140000000000004018000000000000",
    );
    for i in 0..2u8 {
        for j in 0..3u8 {
            want += &hex(&(i as f64).to_be_bytes());
            want += &hex(&(j as f64).to_be_bytes());
        }
    }
    let bytes = sample().encode().unwrap();
    assert_eq!(bytes.len(), 228);
    assert_eq!(hex(&bytes), want);
    assert_eq!(SampleT::decode(&bytes).unwrap(), sample());
    assert_eq!(SampleT::MAGIC, 7);
    assert_eq!(SampleT::OTHER, 16);
    assert_eq!(SampleT::PI.to_string(), "3.14");
    assert_eq!(SampleT::LCM_BASE_HASH, 0x9c8d320bfb075a97);
}

#[test]
fn small_golden_vectors() {
    assert_eq!(
        hex(&TinyT { a: -2 }.encode().unwrap()),
        "d325b9c044c46c1cfffffffe"
    );
    assert_eq!(hex(&EmptyT {}.encode().unwrap()), "000000002468acf0");
    assert_eq!(NodeT::FINGERPRINT, 0x31fe946c75d6e4e7);
    assert_eq!(PointT::FINGERPRINT, 0xa4b2a25c6168910b);
    assert_eq!(
        stride_tests::const_dims::lcmtest3::ArraysT::FINGERPRINT,
        0x87643a5c71617d81
    );
    let a = stride_tests::const_dims::lcmtest3::ArraysT {
        arr: [1; 10],
        m: [[2; 10]; 2],
    };
    assert_eq!(a.encode().unwrap().len(), 8 + 10 + 40);
    let k = KeywordsT {
        r#type: 1,
        r#match: 2.0,
        self_: "s".into(),
    };
    assert_eq!(KeywordsT::decode(&k.encode().unwrap()).unwrap(), k);
}

#[test]
fn a_recursive_tree_round_trips() {
    let leaf = NodeT {
        num_children: 0,
        children: vec![],
    };
    let tree = NodeT {
        num_children: 2,
        children: vec![
            leaf.clone(),
            NodeT {
                num_children: 1,
                children: vec![leaf],
            },
        ],
    };
    let bytes = tree.encode().unwrap();
    assert_eq!(bytes.len(), 8 + 4 * 4);
    assert_eq!(NodeT::decode(&bytes).unwrap(), tree);
}

#[test]
fn inconsistent_sizes_are_refused_when_encoding() {
    let mut s = sample();
    s.n = 3;
    assert!(matches!(
        s.encode(),
        Err(EncodeError::SizeMismatch { field: "n", .. })
    ));
    let mut s = sample();
    s.flags[1].pop();
    assert!(s.encode().is_err());
    let mut s = sample();
    s.name = "nul\0inside".into();
    assert!(matches!(
        s.encode(),
        Err(EncodeError::StringContainsNul { .. })
    ));
}

#[test]
fn hostile_lengths_are_refused_without_allocating() {
    // multidim_t claims 127 x 32767 int32 values in a few bytes.
    let mut bytes = MultidimT::FINGERPRINT.to_be_bytes().to_vec();
    bytes.extend_from_slice(&[0x7f, 0x7f, 0xff]);
    bytes.extend_from_slice(&0i64.to_be_bytes());
    assert!(matches!(
        MultidimT::decode(&bytes),
        Err(DecodeError::LengthTooLarge { .. })
    ));
    // A negative size.
    let mut bytes = SampleT::FINGERPRINT.to_be_bytes().to_vec();
    let good = sample().encode().unwrap();
    bytes.extend_from_slice(&good[8..8 + 8 + 1 + 2 + 4 + 4 + 8 + 7 + 1 + 4]);
    bytes.extend_from_slice(&(-1i32).to_be_bytes());
    assert_eq!(
        SampleT::decode(&bytes),
        Err(DecodeError::NegativeLength(-1))
    );
    // Zero-size elements are accepted only in moderation.
    let mut bytes = MultidimT::FINGERPRINT.to_be_bytes().to_vec();
    bytes.extend_from_slice(&[0x7f, 0, 0]); // a = 127, b = 0
    bytes.extend_from_slice(&0i64.to_be_bytes());
    assert!(MultidimT::decode(&bytes).is_err()); // truncated later, but no huge allocation
}

fn mutate_and_decode<M: Message + Random>(seed: u64, cuts: &[usize], flips: &[(usize, u8)]) {
    let mut rng = Rng::new(seed);
    let mut bytes = M::random(&mut rng).encode().unwrap();
    for &(at, x) in flips {
        if !bytes.is_empty() {
            let i = at % bytes.len();
            bytes[i] ^= x;
        }
    }
    for &c in cuts {
        let _ = M::decode(&bytes[..c.min(bytes.len())]);
    }
    let _ = M::decode(&bytes);
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(400))]

    #[test]
    fn decoders_never_panic_on_mutated_messages(
        seed in proptest::num::u64::ANY,
        cuts in proptest::collection::vec(0usize..400, 0..4),
        flips in proptest::collection::vec((0usize..400, 1u8..=255), 0..6),
    ) {
        mutate_and_decode::<SampleT>(seed, &cuts, &flips);
        mutate_and_decode::<MultidimT>(seed, &cuts, &flips);
        mutate_and_decode::<NodeT>(seed, &cuts, &flips);
        mutate_and_decode::<stride_lcmtypes::stride::JointTrajectoryT>(seed, &cuts, &flips);
        mutate_and_decode::<stride_lcmtypes::stride::FootstepPlanT>(seed, &cuts, &flips);
        mutate_and_decode::<stride_lcmtypes::stride::ObstacleListT>(seed, &cuts, &flips);
        mutate_and_decode::<stride_lcmtypes::stride::PointCloudT>(seed, &cuts, &flips);
        mutate_and_decode::<stride_lcmtypes::stride::ImageT>(seed, &cuts, &flips);
    }

    #[test]
    fn decoders_never_panic_on_garbage(body in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
        fn framed<M: Message>(body: &[u8]) -> Vec<u8> {
            let mut v = M::FINGERPRINT.to_be_bytes().to_vec();
            v.extend_from_slice(body);
            v
        }
        let _ = SampleT::decode(&framed::<SampleT>(&body));
        let _ = MultidimT::decode(&framed::<MultidimT>(&body));
        let _ = NodeT::decode(&framed::<NodeT>(&body));
        let _ = stride_lcmtypes::stride::JointTrajectoryT::decode(&framed::<stride_lcmtypes::stride::JointTrajectoryT>(&body));
        let _ = stride_lcmtypes::stride::StereoImageT::decode(&framed::<stride_lcmtypes::stride::StereoImageT>(&body));
    }
}

#[test]
fn a_table_row_of_the_wrong_width_is_refused_when_encoding() {
    use stride_lcmtypes::stride::JointTrajectoryT;
    let mut t = JointTrajectoryT {
        num_joints: 3,
        joint_names: vec!["a".into(), "b".into(), "c".into()],
        num_rows: 2,
        time_from_start: vec![0.0, 0.01],
        positions: vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]],
        velocities: vec![vec![0.0; 3], vec![0.5; 3]],
        ..Default::default()
    };
    let bytes = t.encode().unwrap();
    assert_eq!(JointTrajectoryT::decode(&bytes).unwrap(), t);
    t.velocities[1].pop();
    assert!(matches!(
        t.encode(),
        Err(EncodeError::SizeMismatch {
            field: "num_joints",
            declared: 3,
            actual: 2
        })
    ));
}
