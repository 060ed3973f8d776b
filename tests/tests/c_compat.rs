//! Every stride type against lcm-gen's C code: the same fingerprint, and for random instances
//! the same bytes both ways (Rust encodes, C decodes and re-encodes, Rust decodes C's bytes).

use lcm::{Message, Random, Rng};
// Links the C side (lcm-gen code and harness) built by this crate's build script.
use stride_tests as _;

const INSTANCES: u64 = 300;

include!(concat!(env!("OUT_DIR"), "/compat_decls.rs"));

fn check<M: Message + Random + PartialEq + std::fmt::Debug>(
    c_fingerprint: unsafe extern "C" fn() -> i64,
    c_roundtrip: unsafe extern "C" fn(*const u8, i32, *mut u8, i32) -> i32,
) -> u64 {
    // SAFETY: a plain C function without arguments.
    let fp = unsafe { c_fingerprint() } as u64;
    assert_eq!(fp, M::FINGERPRINT, "fingerprint of {}", M::TYPE_NAME);
    let mut rng = Rng::new(M::FINGERPRINT);
    let mut bytes_checked = 0;
    for i in 0..INSTANCES {
        rng.set_budget(Rng::DEFAULT_BUDGET);
        let msg = M::random(&mut rng);
        let ours = msg.encode().unwrap();
        assert_eq!(ours.len(), msg.encoded_size(), "{} size", M::TYPE_NAME);
        let mut theirs = vec![0u8; ours.len() + 64];
        // SAFETY: both buffers are valid for the lengths passed.
        let n = unsafe {
            c_roundtrip(
                ours.as_ptr(),
                ours.len() as i32,
                theirs.as_mut_ptr(),
                theirs.len() as i32,
            )
        };
        assert!(n >= 0, "C could not decode {} #{i}: {n}", M::TYPE_NAME);
        theirs.truncate(n as usize);
        assert_eq!(
            theirs,
            ours,
            "C re-encoded {} #{i} differently",
            M::TYPE_NAME
        );
        let back = M::decode(&theirs)
            .unwrap_or_else(|e| panic!("{} #{i} does not decode: {e}\n{msg:?}", M::TYPE_NAME));
        assert_eq!(back, msg, "{} #{i}", M::TYPE_NAME);
        bytes_checked += ours.len() as u64;
    }
    bytes_checked
}

#[test]
fn every_type_is_byte_identical_to_lcm_gen_c() {
    let mut types = 0;
    let mut bytes = 0;
    macro_rules! case {
        ($t:ty, $fp:ident, $rt:ident) => {
            bytes += check::<$t>($fp, $rt);
            types += 1;
        };
    }
    include!(concat!(env!("OUT_DIR"), "/compat_cases.rs"));
    // Every stride type, and the 7 feature-test types of tests/lcm.
    assert_eq!(types, stride_lcmtypes::TYPES.len() + 7);
    eprintln!("{types} types, {INSTANCES} random instances each, {bytes} bytes compared");
}
