//! Random instances of LCM types, for tests (the generated `Random` impls use these).

/// A small deterministic pseudo-random generator (xorshift64*), with a budget of array
/// elements so that random recursive types (trees) stay finite.
#[derive(Debug, Clone)]
pub struct Rng {
    state: u64,
    budget: u64,
}

impl Rng {
    /// Array elements a generator hands out before every further array is empty.
    pub const DEFAULT_BUDGET: u64 = 256;

    /// A generator seeded with `seed` (any value).
    pub fn new(seed: u64) -> Rng {
        Rng {
            state: seed ^ 0x9e37_79b9_7f4a_7c15 | 1,
            budget: Self::DEFAULT_BUDGET,
        }
    }

    /// Resets the element budget (call it before each top-level instance).
    pub fn set_budget(&mut self, elements: u64) {
        self.budget = elements;
    }

    /// An array size: 0 to 3 elements while the budget lasts, 0 after.
    pub fn size(&mut self) -> u64 {
        let n = self.below(4).min(self.budget);
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

    /// A finite double, mixing small, large and negative values.
    pub fn f64(&mut self) -> f64 {
        let mag = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let exp = self.below(40) as i32 - 20;
        let v = mag * 2f64.powi(exp);
        if self.bool() {
            -v
        } else {
            v
        }
    }

    /// A finite float.
    pub fn f32(&mut self) -> f32 {
        self.f64() as f32
    }

    /// A short printable ASCII string without NUL.
    pub fn string(&mut self) -> String {
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
