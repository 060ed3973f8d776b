//! Golden vectors (produced by lcm-gen's C code) and property tests of the generated types.

use lcm::{DecodeError, Message};
use stride_lcmtypes::stride::*;
use stride_lcmtypes::type_name_for_fingerprint;

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

// Vectors produced by lcm-gen 1.3.1's C code for the same instances.
#[test]
fn ping_matches_lcm_gen() {
    let p = PingT {
        header: HeaderT {
            utime: 0x0102030405060708,
            sequence: 7,
            frame: "w".into(),
        },
        sent_utime: -1,
        echoed_by: String::new(),
        payload_size: 3,
        payload: vec![0xaa, 0xbb, 0xcc],
    };
    let bytes = p.encode().unwrap();
    assert_eq!(
        hex(&bytes),
        "c912704d45c5c17a01020304050607080000000000000007000000027700ffffffffffffffff000000010000000003aabbcc"
    );
    assert_eq!(bytes.len(), p.encoded_size());
    assert_eq!(PingT::decode(&bytes).unwrap(), p);
}

#[test]
fn node_status_matches_lcm_gen() {
    let s = NodeStatusT {
        header: HeaderT {
            utime: 1,
            sequence: 2,
            frame: String::new(),
        },
        node: "n".into(),
        host: "h".into(),
        pid: 42,
        state: NodeStatusT::STATE_RUNNING,
        detail: "ok".into(),
        uptime_us: 3,
        messages_published: 4,
        messages_received: 5,
        decode_errors: 6,
        handler_panics: 7,
        messages_lost: 8,
    };
    let bytes = s.encode().unwrap();
    assert_eq!(
        hex(&bytes),
        "f5a3af63b8844c55000000000000000100000000000000020000000100000000026e000000000268000000002a01000000036f6b00000000000000000300000000000000040000000000000005000000000000000600000000000000070000000000000008"
    );
    assert_eq!(NodeStatusT::decode(&bytes).unwrap(), s);
}

#[test]
fn malformed_input_is_an_error() {
    let p = PingT {
        payload_size: 2,
        payload: vec![1, 2],
        ..Default::default()
    };
    let bytes = p.encode().unwrap();
    for cut in 0..bytes.len() {
        assert!(PingT::decode(&bytes[..cut]).is_err());
    }
    let mut wrong = bytes.clone();
    wrong[0] ^= 1;
    assert!(matches!(
        PingT::decode(&wrong),
        Err(DecodeError::Fingerprint { .. })
    ));
    let mut long = bytes.clone();
    long.push(0);
    assert_eq!(PingT::decode(&long), Err(DecodeError::TrailingBytes(1)));
    let bad = PingT {
        payload_size: 5,
        ..Default::default()
    };
    assert!(bad.encode().is_err());
    assert_eq!(
        type_name_for_fingerprint(PingT::FINGERPRINT),
        Some("stride.ping_t")
    );
}

#[test]
fn a_ragged_table_is_an_encode_error_not_an_abort() {
    // Sized by its first row, this table claims 2^14 rows of 2^20 doubles (128 GiB): the
    // encoder must report the short rows, not try to allocate for the claim.
    let rows = 1 << 14;
    let mut t = JointTrajectoryT {
        num_joints: 1 << 20,
        num_rows: rows,
        time_from_start: vec![0.0; rows as usize],
        positions: vec![Vec::new(); rows as usize],
        velocities: vec![Vec::new(); rows as usize],
        ..Default::default()
    };
    t.positions[0] = vec![0.0; 1 << 20];
    assert!(t.encoded_size() > 1 << 37);
    let e = t.encode().unwrap_err();
    assert!(e.to_string().contains("num_joints"), "{e}");
    // Rectangular, it is sized exactly.
    let t = JointTrajectoryT {
        num_joints: 3,
        joint_names: vec!["a".into(), "b".into(), "c".into()],
        num_rows: 2,
        time_from_start: vec![0.0, 0.1],
        positions: vec![vec![0.0; 3]; 2],
        velocities: vec![vec![0.0; 3]; 2],
        ..Default::default()
    };
    assert_eq!(t.encode().unwrap().len(), t.encoded_size());
}

proptest::proptest! {
    #[test]
    fn decoding_garbage_never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..200)) {
        let _ = PingT::decode(&bytes);
        let _ = NodeStatusT::decode(&bytes);
        // Behind a valid fingerprint, the body decoder sees the garbage too.
        let mut framed = PingT::FINGERPRINT.to_be_bytes().to_vec();
        framed.extend_from_slice(&bytes);
        let _ = PingT::decode(&framed);
        let mut framed = NodeStatusT::FINGERPRINT.to_be_bytes().to_vec();
        framed.extend_from_slice(&bytes);
        let _ = NodeStatusT::decode(&framed);
    }

    #[test]
    fn random_pings_round_trip(seq in proptest::num::i64::ANY, frame in "[a-z]{0,12}",
                               payload in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
        let p = PingT {
            header: HeaderT { utime: seq ^ 0x55, sequence: seq, frame },
            sent_utime: seq.wrapping_mul(3),
            echoed_by: "x".into(),
            payload_size: payload.len() as i32,
            payload,
        };
        let bytes = p.encode().unwrap();
        proptest::prop_assert_eq!(bytes.len(), p.encoded_size());
        proptest::prop_assert_eq!(PingT::decode(&bytes).unwrap(), p);
    }
}
