//! Test data shared by the solver's integration tests.

#![allow(dead_code)]

use bake_solver::{Operator, Solution, BANDS};

/// splitmix64: a tiny deterministic generator for test data.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Random positive rows with F_ii = 0, each normalised to sum to 1 (closed, not reciprocal).
pub fn closed_form_factors(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    let mut f = vec![0.0; n * n];
    for i in 0..n {
        let row = &mut f[i * n..(i + 1) * n];
        for (j, v) in row.iter_mut().enumerate() {
            *v = if i == j { 0.0 } else { 0.05 + rng.next_f64() };
        }
        let sum: f64 = row.iter().sum();
        row.iter_mut().for_each(|v| *v /= sum);
    }
    f
}

/// Reciprocal form factors and areas, as a real scene has them: a random symmetric
/// `G_ij = A_i F_ij ≥ 0` (zero diagonal, a quarter of the pairs not seeing each other), and
/// areas chosen so that row i sums to `s_i`: 1 when `open` is false (closed), else in
/// [0.5, 0.95] (light escapes). Returns `(F row-major, areas)`.
pub fn reciprocal_form_factors(n: usize, seed: u64, open: bool) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Rng(seed);
    let mut g = vec![0.0; n * n];
    for i in 0..n {
        for j in i + 1..n {
            let v = rng.next_f64();
            let v = if v < 0.25 { 0.0 } else { v };
            g[i * n + j] = v;
            g[j * n + i] = v;
        }
    }
    let mut area = vec![0.0; n];
    let mut f = vec![0.0; n * n];
    for i in 0..n {
        let s = if open {
            0.5 + 0.45 * rng.next_f64()
        } else {
            1.0
        };
        let row_g: f64 = g[i * n..(i + 1) * n].iter().sum();
        area[i] = row_g / s;
        for j in 0..n {
            f[i * n + j] = g[i * n + j] / area[i];
        }
    }
    (f, area)
}

/// A ring of n elements, each sending half its light to either neighbour: closed, reciprocal
/// (equal areas, symmetric), with eigenvalues cos(2πk/n) spread over [−1, 1]: the hardest
/// spectrum for a Krylov method at a given ρ.
pub fn ring(n: usize) -> Vec<f64> {
    let mut f = vec![0.0; n * n];
    for i in 0..n {
        f[i * n + (i + 1) % n] += 0.5;
        f[i * n + (i + n - 1) % n] += 0.5;
    }
    f
}

pub fn uniform(n: usize, v: [f64; BANDS]) -> Vec<[f64; BANDS]> {
    vec![v; n]
}

/// Coloured reflectances in [0, 0.8] and emission on every 7th element.
pub fn coloured_scene(n: usize, seed: u64) -> (Vec<[f64; BANDS]>, Vec<[f64; BANDS]>) {
    let mut rng = Rng(seed);
    let rho = (0..n)
        .map(|_| {
            [
                0.8 * rng.next_f64(),
                0.8 * rng.next_f64(),
                0.8 * rng.next_f64(),
            ]
        })
        .collect();
    let e = (0..n)
        .map(|i| {
            if i % 7 == 0 {
                [1.0, 2.0, 0.5]
            } else {
                [0.0; 3]
            }
        })
        .collect();
    (rho, e)
}

/// max |a − b| / max |b| over all elements and bands.
pub fn max_rel_diff(a: &[[f64; BANDS]], b: &[[f64; BANDS]]) -> f64 {
    let scale = b.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

pub fn bits(s: &Solution) -> Vec<u64> {
    s.b.iter().flatten().map(|v| v.to_bits()).collect()
}

/// An operator that implements only `apply`, as a matrix-free one might.
pub struct OnlyApply<O>(pub O);

impl<O: Operator> Operator for OnlyApply<O> {
    fn n(&self) -> usize {
        self.0.n()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.0.apply(x, y)
    }
}
