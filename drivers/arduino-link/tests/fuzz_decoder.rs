//! The decoder under garbage, cut frames and damaged frames: no panic, nothing bad comes out,
//! and every good frame sent after the damage arrives.

use proptest::prelude::*;
use stride_link::{Decoder, Frame, Message};

fn frame() -> impl Strategy<Value = Frame> {
    (
        any::<u8>(),
        any::<u8>(),
        prop::collection::vec(prop_oneof![Just(0u8), any::<u8>()], 0..=240),
    )
        .prop_map(|(kind, seq, payload)| Frame { kind, seq, payload })
}

#[derive(Debug, Clone)]
enum Piece {
    Good(Frame),
    Garbage(Vec<u8>),
    Cut(Frame, usize),
    Damaged(Frame, usize, u8),
}

fn piece() -> impl Strategy<Value = Piece> {
    prop_oneof![
        3 => frame().prop_map(Piece::Good),
        1 => prop::collection::vec(any::<u8>(), 0..300).prop_map(Piece::Garbage),
        1 => (frame(), any::<usize>()).prop_map(|(f, at)| Piece::Cut(f, at)),
        1 => (frame(), any::<usize>(), 1u8..=255).prop_map(|(f, at, x)| Piece::Damaged(f, at, x)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn good_frames_survive_damage(pieces in prop::collection::vec(piece(), 1..10), chunk in 1usize..80) {
        let mut stream = Vec::new();
        let mut good = Vec::new();
        for p in &pieces {
            match p {
                Piece::Good(f) => {
                    good.push(f.clone());
                    stream.extend(f.encode().unwrap());
                }
                Piece::Garbage(g) => stream.extend(g),
                Piece::Cut(f, at) => {
                    let w = f.encode().unwrap();
                    stream.extend(&w[..at % w.len()]);
                }
                Piece::Damaged(f, at, x) => {
                    let mut w = f.encode().unwrap();
                    let n = w.len();
                    w[at % n] ^= x;
                    stream.extend(w);
                }
            }
        }
        let mut d = Decoder::new();
        let mut out = Vec::new();
        for c in stream.chunks(chunk) {
            out.extend(d.push(c).into_iter().filter_map(Result::ok));
        }
        // Good frames in order. Nothing else comes out but a cut or damaged frame that is
        // whole after all (cut after its last byte, or damaged in a delimiter).
        let mut it = out.iter();
        for g in &good {
            prop_assert!(it.any(|o| o == g), "lost {:?}", g);
        }
        let sent: Vec<&Frame> = pieces
            .iter()
            .filter_map(|p| match p {
                Piece::Good(f) | Piece::Cut(f, _) | Piece::Damaged(f, _, _) => Some(f),
                Piece::Garbage(_) => None,
            })
            .collect();
        prop_assert!(out.iter().all(|o| sent.contains(&o)), "a frame nobody sent came out");
        for o in &out {
            let _ = Message::parse(o);
        }
    }

    #[test]
    fn decode_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let _ = Frame::decode(&bytes);
        let mut d = Decoder::new();
        for f in d.push(&bytes).into_iter().flatten() {
            let _ = Message::parse(&f);
        }
    }
}
