//! Random instances of LCM types, for tests (the generated `Random` impls use these).

/// A small deterministic pseudo-random generator (xorshift64*), with a budget of array
/// elements so that random recursive types (trees) stay finite.
///
/// [`Rng::new`] draws tame values: finite floats, short printable ASCII strings, arrays of 0
/// to 3 elements. [`Rng::with_edges`] also draws the values a codec gets wrong most easily.
#[derive(Debug, Clone)]
pub struct Rng {
    state: u64,
    budget: u64,
    edges: bool,
}

/// The doubles an edge-value generator draws now and then.
const F64_EDGES: [f64; 14] = [
    f64::NAN,
    -f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.0,
    -0.0,
    f64::MIN_POSITIVE,
    -f64::MIN_POSITIVE,
    5e-324,
    -5e-324,
    f64::MAX,
    f64::MIN,
    f64::EPSILON,
    1.0,
];

/// The floats an edge-value generator draws now and then.
const F32_EDGES: [f32; 14] = [
    f32::NAN,
    -f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    0.0,
    -0.0,
    f32::MIN_POSITIVE,
    -f32::MIN_POSITIVE,
    1e-45,
    -1e-45,
    f32::MAX,
    f32::MIN,
    f32::EPSILON,
    1.0,
];

/// Characters of 1 to 4 bytes in UTF-8 (controls and DEL too, but no NUL) for edge strings.
const EDGE_CHARS: [char; 16] = [
    'a',
    'Z',
    ' ',
    '\t',
    '\n',
    '\u{7f}',
    '"',
    '\\',
    '\u{e9}',
    '\u{df}',
    '\u{3a9}',
    '\u{20ac}',
    '\u{65e5}',
    '\u{fffd}',
    '\u{1f600}',
    '\u{1d11e}',
];

impl Rng {
    /// Array elements a generator hands out before every further array is empty.
    pub const DEFAULT_BUDGET: u64 = 256;

    /// A generator seeded with `seed` (any value).
    pub fn new(seed: u64) -> Rng {
        Rng {
            state: seed ^ 0x9e37_79b9_7f4a_7c15 | 1,
            budget: Self::DEFAULT_BUDGET,
            edges: false,
        }
    }

    /// A generator seeded with `seed` that also draws edge values: NaN, infinities, signed
    /// zeros, subnormal and extreme floats, and any bit pattern; integers' extremes (see
    /// [`Rng::int`]); empty and long arrays (64 to 120 elements while the budget lasts, so
    /// an `int8_t` size still fits); empty, long (up to 600 characters) and non-ASCII UTF-8
    /// strings (characters of 1 to 4 bytes, controls included, never NUL).
    pub fn with_edges(seed: u64) -> Rng {
        Rng {
            edges: true,
            ..Rng::new(seed)
        }
    }

    /// Resets the element budget (call it before each top-level instance).
    pub fn set_budget(&mut self, elements: u64) {
        self.budget = elements;
    }

    /// An array size: 0 to 3 elements while the budget lasts, 0 after (with edges, a quarter
    /// of them 0 and an eighth 64 to 120).
    pub fn size(&mut self) -> u64 {
        let n = if self.edges {
            match self.below(8) {
                0 | 1 => 0,
                2 => 64 + self.below(57),
                _ => self.below(4),
            }
        } else {
            self.below(4)
        };
        let n = n.min(self.budget);
        self.budget -= n;
        n
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.state;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.state = x;
        x.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Random bits for an integer of `bits` bits, to be cast to it. With edges, a quarter of
    /// them are 0, 1, all ones (-1; 255 for a byte), or a signed type's least or greatest
    /// value.
    pub fn int(&mut self, bits: u32) -> u64 {
        if self.edges && self.below(4) == 0 {
            let bits = bits.clamp(1, 64);
            let min = 1u64 << (bits - 1);
            return [0, 1, u64::MAX, min.wrapping_neg(), min - 1][self.below(5) as usize];
        }
        self.next_u64()
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            0
        } else {
            self.next_u64() % n
        }
    }

    /// A boolean.
    pub fn bool(&mut self) -> bool {
        self.next_u64() & 1 == 1
    }

    /// A finite double, mixing small, large and negative values (with edges, a quarter of
    /// them from the edge values and an eighth any bit pattern, NaNs included).
    pub fn f64(&mut self) -> f64 {
        if self.edges {
            match self.below(8) {
                0 | 1 => return F64_EDGES[self.below(F64_EDGES.len() as u64) as usize],
                2 => return f64::from_bits(self.next_u64()),
                _ => {}
            }
        }
        let mag = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let exp = self.below(40) as i32 - 20;
        let v = mag * 2f64.powi(exp);
        if self.bool() {
            -v
        } else {
            v
        }
    }

    /// A finite float (with edges, as [`Rng::f64`] with floats' edge values).
    pub fn f32(&mut self) -> f32 {
        if self.edges {
            match self.below(8) {
                0 | 1 => return F32_EDGES[self.below(F32_EDGES.len() as u64) as usize],
                2 => return f32::from_bits(self.next_u64() as u32),
                _ => {}
            }
        }
        self.f64() as f32
    }

    /// A short printable ASCII string without NUL (with edges, a quarter of them empty, a
    /// quarter up to 600 characters, and half of them of any of `EDGE_CHARS`).
    pub fn string(&mut self) -> String {
        if self.edges {
            let n = match self.below(4) {
                0 => 0,
                1 => 100 + self.below(501) as usize,
                _ => self.below(12) as usize,
            };
            let wide = self.bool();
            return (0..n)
                .map(|_| {
                    if wide {
                        EDGE_CHARS[self.below(EDGE_CHARS.len() as u64) as usize]
                    } else {
                        (b' ' + self.below(95) as u8) as char
                    }
                })
                .collect();
        }
        let n = self.below(12) as usize;
        (0..n)
            .map(|_| (b' ' + self.below(95) as u8) as char)
            .collect()
    }
}

/// Types that can make a random instance of themselves (array sizes kept small).
pub trait Random {
    /// A random instance.
    fn random(rng: &mut Rng) -> Self;
}

#[cfg(test)]
mod tests {
    use super::Rng;

    #[test]
    fn plain_draws_are_tame() {
        let mut rng = Rng::new(7);
        for _ in 0..2000 {
            assert!(rng.f64().is_finite() && rng.f32().is_finite());
            assert!(rng.size() <= 3);
            assert!(rng.string().bytes().all(|b| (b' '..=b'~').contains(&b)));
        }
    }

    #[test]
    fn edge_draws_reach_the_edges() {
        let mut rng = Rng::with_edges(7);
        let (mut i8s, mut i64s, mut f64s) = (Vec::new(), Vec::new(), Vec::new());
        let mut longest = (0, 0);
        for _ in 0..4000 {
            rng.set_budget(Rng::DEFAULT_BUDGET);
            i8s.push(rng.int(8) as i8);
            i64s.push(rng.int(64) as i64);
            f64s.push(rng.f64());
            longest.0 = longest.0.max(rng.size());
            let s = rng.string();
            assert!(!s.contains('\0'));
            longest.1 = longest.1.max(s.chars().count());
        }
        for v in [i8::MIN, i8::MAX, -1, 0, 1] {
            assert!(i8s.contains(&v), "no int8 {v}");
        }
        for v in [i64::MIN, i64::MAX, -1, 0, 1] {
            assert!(i64s.contains(&v), "no int64 {v}");
        }
        assert!(f64s.iter().any(|v| v.is_nan()));
        assert!(f64s.contains(&f64::INFINITY) && f64s.contains(&f64::NEG_INFINITY));
        assert!(
            (64..=120).contains(&longest.0),
            "longest array {}",
            longest.0
        );
        assert!(longest.1 > 500, "longest string {}", longest.1);
    }
}
