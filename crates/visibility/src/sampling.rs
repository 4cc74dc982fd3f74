//! Deterministic random numbers and the stratified point pairs of the visibility estimator.

/// SplitMix64 (Steele, Lea & Flood 2014): a 64-bit state, one add and a mix per number.
/// Passes BigCrush; more than enough for jitter and shuffles.
#[derive(Clone, Copy, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix(self.0)
    }

    /// Uniform in [0, 1), 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in 0..n (n ≥ 1), by Lemire's multiply-shift (bias < n / 2⁶⁴).
    #[inline]
    pub fn below(&mut self, n: usize) -> usize {
        ((self.next_u64() as u128 * n as u128) >> 64) as usize
    }
}

/// SplitMix64's output mix (Stafford's variant 13).
#[inline]
pub(crate) fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The seed of an unordered element pair: the same for (i, j) and (j, i).
pub fn pair_seed(i: usize, j: usize) -> u64 {
    let (lo, hi) = if i <= j { (i, j) } else { (j, i) };
    mix(mix(lo as u64 ^ 0x5eed_0fa1).wrapping_add(hi as u64))
}

/// Largest strata count per side: at most 32² = 1024 sample pairs per element pair.
pub const MAX_STRATA: u32 = 32;

/// Strata per side for a requested sample count: round(√samples), clamped to 1..=32.
pub fn strata(samples: u32) -> usize {
    ((samples as f64).sqrt().round() as u32).clamp(1, MAX_STRATA) as usize
}

/// A random permutation of 0..n (n ≤ 1024) by Fisher–Yates, in a fixed array.
pub(crate) fn shuffle(rng: &mut SplitMix64, n: usize) -> [u16; (MAX_STRATA * MAX_STRATA) as usize] {
    let mut p = [0u16; (MAX_STRATA * MAX_STRATA) as usize];
    for (k, v) in p.iter_mut().enumerate().take(n) {
        *v = k as u16;
    }
    for k in (1..n).rev() {
        p.swap(k, rng.below(k + 1));
    }
    p
}

/// How the point pairs of one element pair are laid out in [0, 1)⁴ = (u_a, v_a, u_b, v_b).
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pattern {
    /// n × n jittered strata on each patch, paired by a random permutation.
    Shuffled,
    /// A randomised orthogonal array of strength 2 (Bose: n prime, rows (i, j), columns
    /// i, j, i + j, i + 2j mod n), jittered: every 2-D projection, including the cross pairs
    /// such as (u_a, u_b), is n × n stratified (Owen 1992; Jarosz et al. 2019).
    OrthogonalArray,
}

/// Primes usable as orthogonal-array strata counts (Bose needs n prime and ≥ 3 for 4 columns).
const PRIMES: [usize; 10] = [3, 5, 7, 11, 13, 17, 19, 23, 29, 31];

/// The point-pair generator of one element pair.
pub(crate) struct Generator {
    pattern: Pattern,
    n: usize,
    inv: f64,
    perm: [u16; (MAX_STRATA * MAX_STRATA) as usize],
    levels: [[u8; 32]; 4],
    rng: SplitMix64,
}

impl Generator {
    pub fn new(pattern: Pattern, samples: u32, seed: u64) -> Generator {
        let mut rng = SplitMix64::new(seed);
        let n = match pattern {
            Pattern::Shuffled => strata(samples),
            Pattern::OrthogonalArray => nearest_prime((samples as f64).sqrt()),
        };
        let perm = if pattern == Pattern::Shuffled {
            shuffle(&mut rng, n * n)
        } else {
            [0; (MAX_STRATA * MAX_STRATA) as usize]
        };
        let mut levels = [[0u8; 32]; 4];
        if pattern != Pattern::Shuffled {
            for column in &mut levels {
                let p = shuffle(&mut rng, n);
                for (l, v) in column.iter_mut().zip(&p[..n]) {
                    *l = *v as u8;
                }
            }
        }
        Generator {
            pattern,
            n,
            inv: 1.0 / n as f64,
            perm,
            levels,
            rng,
        }
    }

    /// Number of point pairs.
    pub fn count(&self) -> usize {
        self.n * self.n
    }

    /// Point pair `k` (call with k = 0, 1, … in order).
    #[inline]
    pub fn coords(&mut self, k: usize) -> [f64; 4] {
        let n = self.n;
        let cells = match self.pattern {
            Pattern::Shuffled => {
                let pk = self.perm[k] as usize;
                [k % n, k / n, pk % n, pk / n]
            }
            Pattern::OrthogonalArray => self.row(k),
        };
        let inv = self.inv;
        let rng = &mut self.rng;
        cells.map(|c| (c as f64 + rng.next_f64()) * inv)
    }

    /// Row k of the randomised Bose array: levels of i, j, i + j, i + 2j (mod n).
    #[inline]
    fn row(&self, k: usize) -> [usize; 4] {
        let n = self.n;
        let (i, j) = (k / n, k % n);
        let raw = [i, j, (i + j) % n, (i + 2 * j) % n];
        [0, 1, 2, 3].map(|c| self.levels[c][raw[c]] as usize)
    }
}

/// Shadow rays (at most) that `samples` gives per pair: n², n the prime nearest √samples,
/// 3 ≤ n ≤ 31 (so 9 ≤ rays ≤ 961; 289 gives 289).
pub fn rays_for(samples: u32) -> u32 {
    let n = nearest_prime((samples as f64).sqrt()) as u32;
    n * n
}

/// The prime in [`PRIMES`] nearest to x.
fn nearest_prime(x: f64) -> usize {
    PRIMES
        .iter()
        .copied()
        .min_by(|&a, &b| (a as f64 - x).abs().total_cmp(&(b as f64 - x).abs()))
        .unwrap_or(3)
}

/// A uniform point of element `k` of `mesh` (a triangle, or a quad as two triangles chosen
/// by area): for rays leaving a surface (the escape estimate, particle checks).
pub fn point_on_element(mesh: &mesher::ElementMesh, k: usize, rng: &mut SplitMix64) -> glam::DVec3 {
    use glam::DVec3;
    let el = &mesh.elements[k];
    let c = el.corners.map(|i| mesh.vertices[i as usize]);
    let triangle = |a: DVec3, b: DVec3, c: DVec3, rng: &mut SplitMix64| {
        let (u, v) = (rng.next_f64(), rng.next_f64());
        let su = u.sqrt();
        a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v)
    };
    if el.sides == 3 {
        return triangle(c[0], c[1], c[2], rng);
    }
    let first = (c[1] - c[0]).cross(c[2] - c[0]).length();
    let second = (c[2] - c[0]).cross(c[3] - c[0]).length();
    if rng.next_f64() * (first + second) < first {
        triangle(c[0], c[1], c[2], rng)
    } else {
        triangle(c[0], c[2], c[3], rng)
    }
}

/// A direction about `normal` with density cos θ / π (Malley's method): the directions light
/// leaves an ideal diffuse surface in.
pub fn cosine_direction(normal: glam::DVec3, rng: &mut SplitMix64) -> glam::DVec3 {
    let (u, v) = (rng.next_f64(), rng.next_f64());
    let (r, phi) = (u.sqrt(), 2.0 * std::f64::consts::PI * v);
    let (t, b) = normal.any_orthonormal_pair();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + normal * (1.0 - u).max(0.0).sqrt()).normalize()
}

#[cfg(test)]
mod tests {
    #[test]
    fn orthogonal_array_rows_cover_every_pair_of_columns() {
        let mut g = Generator::new(Pattern::OrthogonalArray, 49, 5);
        let n = 7;
        let cells: Vec<[usize; 4]> = (0..g.count())
            .map(|k| g.coords(k).map(|x| (x * n as f64) as usize))
            .collect();
        for c1 in 0..4 {
            for c2 in c1 + 1..4 {
                let mut seen = vec![false; n * n];
                for c in &cells {
                    seen[c[c1] * n + c[c2]] = true;
                }
                assert!(seen.iter().all(|&s| s), "columns {c1} {c2}");
            }
        }
    }

    use super::*;

    #[test]
    fn pair_seed_is_symmetric_and_spreads() {
        assert_eq!(pair_seed(3, 9), pair_seed(9, 3));
        assert_ne!(pair_seed(3, 9), pair_seed(3, 10));
        assert_ne!(pair_seed(0, 1), pair_seed(1, 2));
    }

    #[test]
    fn shuffle_is_a_permutation() {
        let mut rng = SplitMix64::new(7);
        let p = shuffle(&mut rng, 100);
        let mut seen = [false; 100];
        for &v in &p[..100] {
            assert!(!seen[v as usize]);
            seen[v as usize] = true;
        }
        assert_eq!(strata(0), 1);
        assert_eq!(strata(64), 8);
        assert_eq!(strata(70), 8);
        assert_eq!(strata(1 << 20), 32);
        assert_eq!(rays_for(0), 9);
        assert_eq!(rays_for(64), 49);
        assert_eq!(rays_for(289), 289);
        assert_eq!(rays_for(256), 289);
        assert_eq!(rays_for(u32::MAX), 961);
    }

    #[test]
    fn uniform_numbers_cover_the_unit_interval() {
        let mut rng = SplitMix64::new(1);
        // Standard error 0.29 / √10⁵ ≈ 0.0009.
        let mean = (0..100_000).map(|_| rng.next_f64()).sum::<f64>() / 100_000.0;
        assert!((mean - 0.5).abs() < 0.004, "{mean}");
    }
}
