//! The Rust codec and the firmware's C codec (`c/stride_link.c`, linked through stride-fakes)
//! agree on random frames, both directions, byte for byte.

use proptest::prelude::*;
use stride_link::{crc16, Decoder, Frame};

// The C codec is linked into stride-fakes (its build compiles it for this test, next to the
// fake board, which runs the firmware on it).
use stride_fakes as _;

#[repr(C)]
struct CFrame {
    kind: u8,
    seq: u8,
    len: u8,
    payload: [u8; 240],
}

extern "C" {
    fn stride_link_crc16(data: *const u8, n: usize, crc: u16) -> u16;
    fn stride_link_encode(f: *const CFrame, out: *mut u8, cap: usize) -> usize;
    fn stride_link_decoder_init(d: *mut u8);
    fn stride_link_decoder_push(d: *mut u8, byte: u8, f: *mut CFrame) -> i32;
}

fn c_encode(f: &Frame) -> Vec<u8> {
    let mut cf = CFrame {
        kind: f.kind,
        seq: f.seq,
        len: f.payload.len() as u8,
        payload: [0; 240],
    };
    cf.payload[..f.payload.len()].copy_from_slice(&f.payload);
    let mut out = vec![0u8; 512];
    // SAFETY: cf and out are valid; out is larger than any encoded frame.
    let n = unsafe { stride_link_encode(&cf, out.as_mut_ptr(), out.len()) };
    out.truncate(n);
    out
}

/// Feeds `bytes` to a C decoder; the frames it completes.
fn c_decode(bytes: &[u8]) -> Vec<Frame> {
    // Storage for the C decoder (its struct is well under 1 KiB), 8-byte aligned.
    let mut dec = vec![0u64; 128];
    let d = dec.as_mut_ptr().cast::<u8>();
    // SAFETY: d points to zeroed storage larger than stride_link_decoder.
    unsafe { stride_link_decoder_init(d) };
    let mut out = Vec::new();
    for &b in bytes {
        let mut cf = CFrame {
            kind: 0,
            seq: 0,
            len: 0,
            payload: [0; 240],
        };
        // SAFETY: as above; cf is a valid frame to write into.
        if unsafe { stride_link_decoder_push(d, b, &mut cf) } == 1 {
            out.push(Frame {
                kind: cf.kind,
                seq: cf.seq,
                payload: cf.payload[..cf.len as usize].to_vec(),
            });
        }
    }
    out
}

fn frame() -> impl Strategy<Value = Frame> {
    (
        any::<u8>(),
        any::<u8>(),
        prop::collection::vec(prop_oneof![Just(0u8), any::<u8>()], 0..=240),
    )
        .prop_map(|(kind, seq, payload)| Frame { kind, seq, payload })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn both_codecs_agree(frames in prop::collection::vec(frame(), 1..6), noise in prop::collection::vec(any::<u8>(), 0..40)) {
        let mut stream = noise.clone();
        for f in &frames {
            let rust = f.encode().unwrap();
            let c = c_encode(f);
            prop_assert_eq!(&rust, &c);
            stream.extend(c);
        }
        // C decodes what Rust encoded, Rust decodes what C encoded: the same frames.
        let from_c = c_decode(&stream);
        let mut d = Decoder::new();
        let from_rust: Vec<Frame> = d.push(&stream).into_iter().filter_map(Result::ok).collect();
        prop_assert_eq!(&from_c, &from_rust);
        prop_assert!(from_rust.ends_with(&frames));
        // SAFETY: a plain function over a valid slice.
        let c_crc = unsafe { stride_link_crc16(noise.as_ptr(), noise.len(), 0xffff) };
        prop_assert_eq!(c_crc, crc16(&noise, 0xffff));
    }
}
