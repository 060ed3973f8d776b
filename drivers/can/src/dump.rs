//! The text format of `candump -L` (can-utils), which `canplayer` and `log2asc` read:
//! `(seconds.micros) iface ID#DATA`, `R` after the `#` for a remote frame (with its length
//! when not 0), 3 hex digits for standard and 8 for extended identifiers.

use crate::{CanFrame, ExtendedId, Id, StandardId};

/// A frame as a `candump -L` line, seen at `utime_us` (µs since the Unix epoch) on `iface`.
pub fn format(utime_us: i64, iface: &str, f: &CanFrame) -> String {
    let id = if f.is_extended() {
        format!("{:08X}", f.raw_id())
    } else {
        format!("{:03X}", f.raw_id())
    };
    let data = if f.is_remote() {
        if f.dlc() == 0 {
            "R".to_owned()
        } else {
            format!("R{}", f.dlc())
        }
    } else {
        f.data().iter().map(|b| format!("{b:02X}")).collect()
    };
    format!(
        "({}.{:06}) {iface} {id}#{data}",
        utime_us.div_euclid(1_000_000),
        utime_us.rem_euclid(1_000_000)
    )
}

/// Reads a `candump -L` line: time (µs), interface, frame; `None` when it is not one.
pub fn parse(line: &str) -> Option<(i64, String, CanFrame)> {
    let mut parts = line.split_whitespace();
    let stamp = parts.next()?.strip_prefix('(')?.strip_suffix(')')?;
    let (secs, micros) = stamp.split_once('.')?;
    let digits = |s: &str, hex: bool| {
        !s.is_empty()
            && s.bytes().all(|b| {
                if hex {
                    b.is_ascii_hexdigit()
                } else {
                    b.is_ascii_digit()
                }
            })
    };
    if micros.len() != 6 || !digits(secs, false) || !digits(micros, false) {
        return None;
    }
    let utime = secs
        .parse::<i64>()
        .ok()?
        .checked_mul(1_000_000)?
        .checked_add(micros.parse::<i64>().ok()?)?;
    let iface = parts.next()?.to_owned();
    let (id, data) = parts.next()?.split_once('#')?;
    if parts.next().is_some() || !digits(id, true) {
        return None;
    }
    let raw = u32::from_str_radix(id, 16).ok()?;
    let id = match id.len() {
        3 => Id::Standard(StandardId::new(u16::try_from(raw).ok()?)?),
        8 => Id::Extended(ExtendedId::new(raw)?),
        _ => return None,
    };
    let frame = if let Some(len) = data.strip_prefix('R') {
        let dlc = if len.is_empty() { 0 } else { len.parse().ok()? };
        CanFrame::remote(id, dlc).ok()?
    } else {
        if data.len() % 2 != 0 || !(data.is_empty() || digits(data, true)) {
            return None;
        }
        let bytes: Option<Vec<u8>> = (0..data.len() / 2)
            .map(|i| u8::from_str_radix(&data[2 * i..2 * i + 2], 16).ok())
            .collect();
        CanFrame::data_frame(id, &bytes?).ok()?
    };
    Some((utime, iface, frame))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candump_lines_both_ways() {
        let f = CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
        let line = format(1_000_000, "can0", &f);
        assert_eq!(line, "(1.000000) can0 601#4041600000000000");
        assert_eq!(parse(&line), Some((1_000_000, "can0".into(), f)));
        let e = CanFrame::extended(0x1234, &[1]).unwrap();
        assert_eq!(
            format(1_500_000, "slcan0", &e),
            "(1.500000) slcan0 00001234#01"
        );
        let r = CanFrame::remote(Id::Standard(StandardId::new(0x705).unwrap()), 1).unwrap();
        assert!(format(0, "x", &r).ends_with("705#R1"));
        assert_eq!(parse("(0.000000) x 705#R1").map(|p| p.2), Some(r));
        let empty = CanFrame::standard(0x80, &[]).unwrap();
        assert_eq!(parse(&format(7, "x", &empty)).map(|p| p.2), Some(empty));
        for bad in [
            "",
            "(1.0) can0 601#00",
            "(1.000000) can0 6011#00",
            "(1.000000) can0 601#0",
        ] {
            assert_eq!(parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn a_bad_line_is_refused_never_a_panic() {
        for bad in [
            "(99999999999999999.000000) can0 601#00",
            "(+1.000000) can0 601#00",
            "(1.+00000) can0 601#00",
            "(1.000000) can0 +01#00",
            "(1.000000) can0 601#+1",
            "(1.000000) can0 601#-1",
            "(1.000000) can0 601#é0",
        ] {
            assert_eq!(parse(bad), None, "{bad}");
        }
    }

    proptest::proptest! {
        #[test]
        fn any_line_parses_or_is_refused(line in "\\PC{0,60}") {
            let _ = parse(&line);
        }

        #[test]
        fn a_written_line_reads_back(
            secs in 0i64..4_000_000_000,
            micros in 0i64..1_000_000,
            id in 0u16..0x800,
            data in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..=8),
        ) {
            let f = CanFrame::standard(id, &data).unwrap();
            let t = secs * 1_000_000 + micros;
            proptest::prop_assert_eq!(parse(&format(t, "can0", &f)), Some((t, "can0".into(), f)));
        }
    }
}
