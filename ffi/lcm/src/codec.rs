//! The LCM wire encoding: the [`Message`] trait and big-endian primitive codecs.
//!
//! Pure code, no I/O. The encoding is the one of `lcm-gen`: an 8-byte big-endian fingerprint,
//! then the members in declaration order, big-endian, strings as `int32 length (with NUL)` +
//! bytes + NUL, arrays without a length prefix (their size is an earlier member).

/// Why encoding a message failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// A string contains a NUL byte, which the C decoder would cut at.
    #[error("string member contains a NUL byte at offset {offset}")]
    StringContainsNul {
        /// Byte offset of the first NUL.
        offset: usize,
    },
    /// A string or array is longer than its length field can say.
    #[error("length {len} does not fit the length field")]
    LengthOverflow {
        /// The length.
        len: usize,
    },
    /// A variable-length array's size member disagrees with the array's real length.
    #[error("size member {field} is {declared} but the array has {actual} elements")]
    SizeMismatch {
        /// The size member's name.
        field: &'static str,
        /// Its value.
        declared: i64,
        /// The array's length.
        actual: usize,
    },
}

/// Why decoding a message failed. Decoding never panics and never trusts a length further
/// than the bytes actually present.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// The first 8 bytes are not this type's fingerprint.
    #[error(
        "fingerprint mismatch for {type_name}: expected {expected:#018x}, found {found:#018x}"
    )]
    Fingerprint {
        /// The type being decoded.
        type_name: &'static str,
        /// Its fingerprint.
        expected: u64,
        /// What the bytes carried.
        found: u64,
    },
    /// The buffer ended early.
    #[error("truncated: needed {needed} more bytes, {remaining} left")]
    Truncated {
        /// Bytes wanted.
        needed: usize,
        /// Bytes left.
        remaining: usize,
    },
    /// A string or array length is negative.
    #[error("negative length {0}")]
    NegativeLength(i64),
    /// A length is larger than the bytes left could hold.
    #[error("length {len} cannot fit in the {remaining} bytes left")]
    LengthTooLarge {
        /// The length read.
        len: i64,
        /// Bytes left.
        remaining: usize,
    },
    /// A boolean byte other than 0 or 1.
    #[error("invalid boolean byte {0:#04x}")]
    InvalidBool(u8),
    /// A string is not valid UTF-8.
    #[error("string is not valid UTF-8")]
    InvalidUtf8,
    /// A string is not NUL-terminated, or has a NUL inside.
    #[error("string is not a single NUL-terminated run")]
    BadStringTerminator,
    /// Bytes remain after the message.
    #[error("{0} trailing bytes after the message")]
    TrailingBytes(usize),
}

/// Appends big-endian LCM primitives to a byte vector.
#[derive(Debug)]
pub struct Encoder<'a> {
    buf: &'a mut Vec<u8>,
}

macro_rules! put_num {
    ($($name:ident: $t:ty),* $(,)?) => {$(
        #[doc = concat!("Appends a big-endian `", stringify!($t), "`.")]
        #[inline]
        pub fn $name(&mut self, v: $t) {
            self.buf.extend_from_slice(&v.to_be_bytes());
        }
    )*};
}

/// Writes `v` converted by `conv` at `dst`, in groups of four (the compiler then swaps bytes
/// with vector instructions even in short rows, a joint vector, where it would not vectorize a
/// plain loop); returns how many it wrote.
///
/// # Safety
/// `dst` must have room for `v.len()` values.
#[inline(always)]
unsafe fn fill<T, B>(dst: *mut B, v: &[T], conv: fn(&T) -> B) -> usize {
    let mut groups = v.chunks_exact(4);
    let mut i = 0;
    for g in &mut groups {
        let w = [conv(&g[0]), conv(&g[1]), conv(&g[2]), conv(&g[3])];
        // SAFETY: room for v.len() values (the caller's promise); unaligned write.
        unsafe { dst.add(i).cast::<[B; 4]>().write_unaligned(w) };
        i += 4;
    }
    for x in groups.remainder() {
        // SAFETY: as above.
        unsafe { dst.add(i).write_unaligned(conv(x)) };
        i += 1;
    }
    i
}

macro_rules! put_slice {
    ($($name:ident, $rows:ident: $t:ty => $bits:ty, $conv:expr);* $(;)?) => {$(
        #[doc = concat!("Appends a slice of big-endian `", stringify!($t), "` (an array member).")]
        #[inline]
        pub fn $name(&mut self, v: &[$t]) {
            const N: usize = std::mem::size_of::<$t>();
            let bytes = v.len() * N;
            self.buf.reserve(bytes);
            let start = self.buf.len();
            let dst = self.buf.spare_capacity_mut()[..bytes]
                .as_mut_ptr()
                .cast::<$bits>();
            // SAFETY: `dst` has room for v.len() values (reserved above).
            unsafe { fill(dst, v, $conv) };
            // SAFETY: `fill` initialised all `bytes` bytes after `start`.
            unsafe { self.buf.set_len(start + bytes) };
        }

        #[doc = concat!("Appends the rows of a two-dimensional `", stringify!($t), "` array whose rows must each hold `declared` values (the size member `field`): all checked first, then written in one pass.")]
        pub fn $rows(
            &mut self,
            rows: &[Vec<$t>],
            declared: i64,
            field: &'static str,
        ) -> Result<(), EncodeError> {
            const N: usize = std::mem::size_of::<$t>();
            for r in rows {
                if r.len() as i64 != declared {
                    return Err(EncodeError::SizeMismatch { field, declared, actual: r.len() });
                }
            }
            let bytes = rows.len() * declared.max(0) as usize * N;
            self.buf.reserve(bytes);
            let start = self.buf.len();
            let dst = self.buf.spare_capacity_mut()[..bytes]
                .as_mut_ptr()
                .cast::<$bits>();
            let mut i = 0;
            for r in rows {
                // SAFETY: the rows hold `bytes / N` values in all (checked above), and `dst`
                // has room for them (reserved above).
                i += unsafe { fill(dst.add(i), r, $conv) };
            }
            // SAFETY: the loop above initialised all `bytes` bytes after `start`.
            unsafe { self.buf.set_len(start + bytes) };
            Ok(())
        }
    )*};
}

impl<'a> Encoder<'a> {
    put_slice!(
        put_i8_slice, put_i8_rows: i8 => i8, |x| *x;
        put_i16_slice, put_i16_rows: i16 => i16, |x| x.to_be();
        put_i32_slice, put_i32_rows: i32 => i32, |x| x.to_be();
        put_i64_slice, put_i64_rows: i64 => i64, |x| x.to_be();
        put_f32_slice, put_f32_rows: f32 => u32, |x| x.to_bits().to_be();
        put_f64_slice, put_f64_rows: f64 => u64, |x| x.to_bits().to_be();
    );

    /// Appends a `byte` array (same as [`Encoder::put_bytes`]).
    #[inline]
    pub fn put_u8_slice(&mut self, v: &[u8]) {
        self.buf.extend_from_slice(v);
    }

    /// Appends the rows of a two-dimensional `byte` array whose rows must each hold
    /// `declared` bytes (the size member `field`).
    pub fn put_u8_rows(
        &mut self,
        rows: &[Vec<u8>],
        declared: i64,
        field: &'static str,
    ) -> Result<(), EncodeError> {
        for r in rows {
            if r.len() as i64 != declared {
                return Err(EncodeError::SizeMismatch {
                    field,
                    declared,
                    actual: r.len(),
                });
            }
        }
        for r in rows {
            self.buf.extend_from_slice(r);
        }
        Ok(())
    }

    /// Wraps a buffer; bytes are appended after its current contents.
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        Encoder { buf }
    }

    put_num!(put_i8: i8, put_i16: i16, put_i32: i32, put_i64: i64, put_f32: f32, put_f64: f64, put_u64: u64);

    /// Appends a byte.
    #[inline]
    pub fn put_u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// Appends a boolean as 0 or 1.
    #[inline]
    pub fn put_bool(&mut self, v: bool) {
        self.buf.push(v as u8);
    }

    /// Appends raw bytes (a `byte` array).
    #[inline]
    pub fn put_bytes(&mut self, v: &[u8]) {
        self.buf.extend_from_slice(v);
    }

    /// Appends a string: length including the NUL, the bytes, the NUL.
    pub fn put_str(&mut self, s: &str) -> Result<(), EncodeError> {
        if let Some(offset) = s.bytes().position(|b| b == 0) {
            return Err(EncodeError::StringContainsNul { offset });
        }
        let len = i32::try_from(s.len() + 1)
            .map_err(|_| EncodeError::LengthOverflow { len: s.len() + 1 })?;
        self.put_i32(len);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
        Ok(())
    }

    /// Number of bytes in the underlying buffer.
    pub fn len(&self) -> usize {
        self.buf.len()
    }

    /// True when the underlying buffer is empty.
    pub fn is_empty(&self) -> bool {
        self.buf.is_empty()
    }
}

/// Reads big-endian LCM primitives from a byte slice, checking every length.
#[derive(Debug, Clone)]
pub struct Decoder<'a> {
    buf: &'a [u8],
}

macro_rules! get_num {
    ($($name:ident: $t:ty),* $(,)?) => {$(
        #[doc = concat!("Reads a big-endian `", stringify!($t), "`.")]
        #[inline]
        pub fn $name(&mut self) -> Result<$t, DecodeError> {
            let b = self.take(std::mem::size_of::<$t>())?;
            Ok(<$t>::from_be_bytes(b.try_into().expect("length checked")))
        }
    )*};
}

macro_rules! get_into {
    ($($name:ident: $t:ty),* $(,)?) => {$(
        #[doc = concat!("Fills `out` with big-endian `", stringify!($t), "` values (an array member).")]
        #[inline]
        pub fn $name(&mut self, out: &mut [$t]) -> Result<(), DecodeError> {
            const N: usize = std::mem::size_of::<$t>();
            let bytes = self.take(out.len() * N)?;
            for (x, chunk) in out.iter_mut().zip(bytes.chunks_exact(N)) {
                *x = <$t>::from_be_bytes(chunk.try_into().expect("chunk size"));
            }
            Ok(())
        }
    )*};
}

impl<'a> Decoder<'a> {
    get_into!(get_i8_into: i8, get_i16_into: i16, get_i32_into: i32, get_i64_into: i64, get_f32_into: f32, get_f64_into: f64);

    /// Fills `out` with the next bytes (a `byte` array).
    #[inline]
    pub fn get_u8_into(&mut self, out: &mut [u8]) -> Result<(), DecodeError> {
        out.copy_from_slice(self.take(out.len())?);
        Ok(())
    }

    /// Starts reading at the beginning of `buf`.
    pub fn new(buf: &'a [u8]) -> Self {
        Decoder { buf }
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.buf.len()
    }

    /// Takes the next `n` bytes.
    #[inline]
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        if n > self.buf.len() {
            return Err(DecodeError::Truncated {
                needed: n,
                remaining: self.buf.len(),
            });
        }
        let (head, tail) = self.buf.split_at(n);
        self.buf = tail;
        Ok(head)
    }

    get_num!(get_i8: i8, get_i16: i16, get_i32: i32, get_i64: i64, get_f32: f32, get_f64: f64, get_u64: u64);

    /// Reads a byte.
    #[inline]
    pub fn get_u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.take(1)?[0])
    }

    /// Reads a boolean, refusing bytes other than 0 and 1.
    #[inline]
    pub fn get_bool(&mut self) -> Result<bool, DecodeError> {
        match self.get_u8()? {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(DecodeError::InvalidBool(b)),
        }
    }

    /// Reads a string: length with NUL, bytes, NUL; UTF-8 checked.
    pub fn get_string(&mut self) -> Result<String, DecodeError> {
        let len = self.get_i32()? as i64;
        let n = self.check_len(len, 1)?;
        if n == 0 {
            return Err(DecodeError::BadStringTerminator);
        }
        let bytes = self.take(n)?;
        let (body, nul) = bytes.split_at(n - 1);
        if nul[0] != 0 || body.contains(&0) {
            return Err(DecodeError::BadStringTerminator);
        }
        std::str::from_utf8(body)
            .map(str::to_owned)
            .map_err(|_| DecodeError::InvalidUtf8)
    }

    /// Converts a decoded length member to `usize`, refusing negative lengths and lengths whose
    /// elements (at least `min_elem_size` bytes each) cannot fit in what is left. This bounds
    /// every allocation by the input size. Elements that may encode to nothing (an inner array
    /// of size 0) are allowed up to [`Decoder::MAX_EMPTY_ELEMENTS`].
    pub fn check_len(&self, len: i64, min_elem_size: usize) -> Result<usize, DecodeError> {
        let too_large = || DecodeError::LengthTooLarge {
            len,
            remaining: self.buf.len(),
        };
        if len < 0 {
            return Err(DecodeError::NegativeLength(len));
        }
        let n = usize::try_from(len).map_err(|_| too_large())?;
        let fits = if min_elem_size == 0 {
            n <= Self::MAX_EMPTY_ELEMENTS
        } else {
            n.saturating_mul(min_elem_size) <= self.buf.len()
        };
        if fits {
            Ok(n)
        } else {
            Err(too_large())
        }
    }

    /// How many elements that encode to no bytes at all an array may claim.
    pub const MAX_EMPTY_ELEMENTS: usize = 1 << 16;
}

/// A type with an LCM encoding: what `lcm-gen` would generate for a `struct` in a `.lcm` file.
///
/// Implementors provide the body codec; the provided methods add and check the fingerprint.
/// Nested types use the body codec only (LCM puts no fingerprint on nested members).
pub trait Message: Sized {
    /// The lcm-gen fingerprint (the first 8 bytes of every encoded message).
    const FINGERPRINT: u64;
    /// The fully qualified LCM type name, e.g. `stride.node_status_t`.
    const TYPE_NAME: &'static str;

    /// Size of the body in bytes (the encoded size without the fingerprint) of a message that
    /// encodes; a table whose rows differ in length, which does not, is sized by its first.
    fn body_size(&self) -> usize;
    /// Appends the body (no fingerprint).
    fn encode_body(&self, enc: &mut Encoder<'_>) -> Result<(), EncodeError>;
    /// Reads a body (no fingerprint).
    fn decode_body(dec: &mut Decoder<'_>) -> Result<Self, DecodeError>;

    /// The per-publisher sequence number this message carries, if its type has one. Typed
    /// subscriptions use it to count lost messages.
    fn sequence(&self) -> Option<i64> {
        None
    }

    /// Full encoded size: 8 bytes of fingerprint plus the body.
    fn encoded_size(&self) -> usize {
        8 + self.body_size()
    }

    /// Appends fingerprint and body to `buf`.
    fn encode_into(&self, buf: &mut Vec<u8>) -> Result<(), EncodeError> {
        // The size is a hint: a message that does not encode may claim more than there is
        // memory for, and must get its error, not an abort.
        let _ = buf.try_reserve(self.encoded_size());
        let mut enc = Encoder::new(buf);
        enc.put_u64(Self::FINGERPRINT);
        self.encode_body(&mut enc)
    }

    /// Encodes fingerprint and body into a new vector.
    fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        let mut buf = Vec::new();
        self.encode_into(&mut buf)?;
        Ok(buf)
    }

    /// Decodes a whole message: checks the fingerprint, the body, and that nothing trails it.
    fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        let mut dec = Decoder::new(bytes);
        let found = dec.get_u64()?;
        if found != Self::FINGERPRINT {
            return Err(DecodeError::Fingerprint {
                type_name: Self::TYPE_NAME,
                expected: Self::FINGERPRINT,
                found,
            });
        }
        let msg = Self::decode_body(&mut dec)?;
        match dec.remaining() {
            0 => Ok(msg),
            n => Err(DecodeError::TrailingBytes(n)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_are_big_endian() {
        let mut v = Vec::new();
        let mut e = Encoder::new(&mut v);
        e.put_i16(-2);
        e.put_i32(0x11223344);
        e.put_f32(1.5);
        e.put_bool(true);
        e.put_str("hi").unwrap();
        e.put_str("").unwrap();
        assert_eq!(
            v,
            [
                0xff, 0xfe, 0x11, 0x22, 0x33, 0x44, 0x3f, 0xc0, 0, 0, 1, 0, 0, 0, 3, b'h', b'i', 0,
                0, 0, 0, 1, 0
            ]
        );
        let mut d = Decoder::new(&v);
        assert_eq!(d.get_i16().unwrap(), -2);
        assert_eq!(d.get_i32().unwrap(), 0x11223344);
        assert_eq!(d.get_f32().unwrap(), 1.5);
        assert!(d.get_bool().unwrap());
        assert_eq!(d.get_string().unwrap(), "hi");
        assert_eq!(d.get_string().unwrap(), "");
        assert_eq!(d.remaining(), 0);
    }

    #[test]
    fn string_with_nul_is_refused() {
        let mut v = Vec::new();
        assert_eq!(
            Encoder::new(&mut v).put_str("a\0b"),
            Err(EncodeError::StringContainsNul { offset: 1 })
        );
    }

    #[test]
    fn hostile_lengths_are_errors() {
        // Negative string length.
        let mut d = Decoder::new(&[0xff, 0xff, 0xff, 0xff, 0]);
        assert_eq!(d.get_string(), Err(DecodeError::NegativeLength(-1)));
        // Huge string length with few bytes behind it.
        let mut d = Decoder::new(&[0x7f, 0xff, 0xff, 0xff, 0]);
        assert!(matches!(
            d.get_string(),
            Err(DecodeError::LengthTooLarge { .. })
        ));
        // Zero-length string (no NUL) is malformed.
        let mut d = Decoder::new(&[0, 0, 0, 0]);
        assert_eq!(d.get_string(), Err(DecodeError::BadStringTerminator));
        // Missing terminator.
        let mut d = Decoder::new(&[0, 0, 0, 2, b'a', b'b']);
        assert_eq!(d.get_string(), Err(DecodeError::BadStringTerminator));
        // Array of a billion doubles in 8 bytes.
        let d = Decoder::new(&[0; 8]);
        assert!(d.check_len(1_000_000_000, 8).is_err());
        assert_eq!(d.check_len(1, 8), Ok(1));
        // Bad boolean.
        assert_eq!(
            Decoder::new(&[2]).get_bool(),
            Err(DecodeError::InvalidBool(2))
        );
        // Truncation.
        assert_eq!(
            Decoder::new(&[1, 2]).get_i32(),
            Err(DecodeError::Truncated {
                needed: 4,
                remaining: 2
            })
        );
    }

    #[test]
    fn bulk_slices_match_scalars() {
        let v = [1.5f64, -2.0, 3.25];
        let mut a = Vec::new();
        Encoder::new(&mut a).put_f64_slice(&v);
        let mut b = Vec::new();
        let mut e = Encoder::new(&mut b);
        for x in v {
            e.put_f64(x);
        }
        assert_eq!(a, b);
        let mut back = [0f64; 3];
        Decoder::new(&a).get_f64_into(&mut back).unwrap();
        assert_eq!(back, v);
        let mut short = [0i32; 4];
        assert!(Decoder::new(&[0; 15]).get_i32_into(&mut short).is_err());
    }

    proptest::proptest! {
        #[test]
        fn decoder_never_panics_on_garbage(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..64)) {
            let mut d = Decoder::new(&bytes);
            while d.remaining() > 0 {
                if d.get_string().is_err() && d.get_u8().is_err() {
                    break;
                }
            }
        }

        #[test]
        fn strings_round_trip(s in "[^\u{0}]{0,40}") {
            let mut v = Vec::new();
            Encoder::new(&mut v).put_str(&s).unwrap();
            let mut d = Decoder::new(&v);
            proptest::prop_assert_eq!(d.get_string().unwrap(), s);
            proptest::prop_assert_eq!(d.remaining(), 0);
        }
    }
}
