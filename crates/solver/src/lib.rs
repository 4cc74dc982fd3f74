//! Solves the radiosity system per colour band.
//!
//! Goral et al. 1984, eq. 7 (the matrix of §3): for every element `i` and colour band `c`
//!
//! ```text
//! b_i = e_i + ρ_i Σ_j F_ij b_j        i.e.        (I − diag(ρ_c) F) b_c = e_c
//! ```
//!
//! where `F_ij` is the fraction of the light leaving element `i` that reaches element `j`.
//! This crate is pure linear algebra and knows no geometry. `F` is reached through the
//! [`Operator`] trait (`y = F x`), so a matrix-free or hierarchical operator can replace the
//! dense one ([`DenseMatrix`]) for everything but [`solve_direct`], which needs the entries.
//!
//! Three solvers:
//! - [`solve_direct`]: LU with partial pivoting (faer) of `I − diag(ρ_c) F`, one factorisation
//!   per distinct ρ band (a grey scene is factored once).
//! - [`solve_iterative`]: restarted GMRES on the same system through [`Operator::apply`] only,
//!   to a relative-residual tolerance within an iteration budget; it fails with
//!   [`SolveError::NotConverged`] rather than return an unconverged answer.
//! - [`solve_bounces`]: the Neumann series truncated after exactly K interreflections
//!   (the paper's Figure 7 progression).
//!
//! [`energy_balance`] checks a solution against conservation of energy: emitted power =
//! absorbed power + power escaping through openings.
//!
//! # Condition estimate and meaningless systems
//! Both exact solvers report `cond_∞(A)` of `A = I − diag(ρ_c) F` per band
//! ([`Solution::condition`]), from one extra solve `A z = 1`:
//!
//! ```text
//! cond_∞(A) = ‖A‖∞ ‖A⁻¹‖∞,   ‖A⁻¹‖∞ = ‖A⁻¹ 1‖∞ = max_i z_i   when A⁻¹ ≥ 0 entrywise.
//! ```
//!
//! `A⁻¹ = Σ_k (diag(ρ) F)^k ≥ 0` whenever `F ≥ 0` and light decays (spectral radius of
//! `diag(ρ) F` below 1), which is the physics of eq. 7; `z_i` is then the expected number of
//! reflections (plus one) of light leaving element `i`. `‖A⁻¹ v‖∞ / ‖v‖∞ ≤ ‖A⁻¹‖∞` for any `v`,
//! so the estimate (the larger of `z` and the `b / e` ratio of the solved bands) is a lower
//! bound on `cond_∞` in every case and exact for physical operators.
//!
//! A band is refused as [`SolveError::Singular`] (never returned with NaN, infinities or
//! digits that mean nothing) when its solution is non-finite; when `min_i z_i < 1/2` (light is
//! amplified: `z ≥ 1` for every physical system); or when `cond_∞ · η ≥ 1`, i.e. no digit of
//! `b` is guaranteed, where `η = max(n ε, max_i (ρ_i Σ_j F_ij − 1))` is the relative error of
//! the operator that is visible from the operator alone: round-off, and rows whose reflected
//! fraction exceeds 1 (physically `Σ_j F_ij ≤ 1`, eq. 15, so any excess is integration error).
//! A closed scene with ρ = 1 everywhere and an emitter has no finite solution; with form
//! factors whose rows sum to 1 within δ its condition number is about `1/δ`, so it is refused
//! whenever some row exceeds 1 by a similar δ. (When every row falls short of 1 instead, the
//! operator describes a leaky box: its answer is large, finite, and balanced by the light that
//! escapes through the leak, see [`energy_balance`].)
//!
//! # Determinism
//! Every result is bit-identical for any rayon thread count (checked by the test
//! `results_do_not_depend_on_thread_count` with 1 to 4 threads). [`DenseMatrix::apply`] sums
//! every row sequentially in index order, whichever thread computes it. faer 0.24's parallel LU
//! (`Par::Rayon`) gives different bits for 1 and 2 threads, so each factorisation and its
//! triangular solves run with `Par::Seq`; determinism beats speed here. The (up to three)
//! factorisations of a coloured scene run in parallel with each other instead. Results may differ
//! across CPUs, since faer picks its SIMD kernels at run time.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::{factor, solve};
use faer::{Conj, Mat, MatRef, Par};
use rayon::prelude::*;
use thiserror::Error;

mod energy;
mod iterative;

pub use energy::{energy_balance, energy_balance_lit, EnergyBalance};
pub use iterative::{solve_iterative, IterativeOptions};

/// Number of colour bands (r, g, b).
pub const BANDS: usize = 3;

/// Row count from which [`DenseMatrix::apply`] spreads rows over rayon threads.
const PAR_MIN_ROWS: usize = 128;

/// A linear operator `y = F x` on vectors of length [`Operator::n`], `F` being the form-factor
/// matrix (`F_ij`: fraction of the light leaving element `i` that reaches element `j`).
pub trait Operator: Sync {
    /// Number of elements (the size of `F`).
    fn n(&self) -> usize;

    /// `y = F x`, i.e. `y_i = Σ_j F_ij x_j`. `x` and `y` have length [`Operator::n`]
    /// (callers in this crate check that).
    fn apply(&self, x: &[f64], y: &mut [f64]);

    /// `y[i][c] = Σ_j F_ij x[j][c]` for the three bands. Must give the same bits as three
    /// calls to [`Operator::apply`]; the default does exactly that, implementors may fuse the
    /// bands into one pass over `F`.
    fn apply_bands(&self, x: &[[f64; BANDS]], y: &mut [[f64; BANDS]]) {
        let n = self.n();
        let mut xc = vec![0.0; n];
        let mut yc = vec![0.0; n];
        for c in 0..BANDS {
            for (xi, x) in xc.iter_mut().zip(x) {
                *xi = x[c];
            }
            self.apply(&xc, &mut yc);
            for (y, yi) in y.iter_mut().zip(&yc) {
                y[c] = *yi;
            }
        }
    }

    /// A bound on the error of `F`'s row sums that the operator's producer knows (e.g. the
    /// form-factor integrator's accuracy). It enters `η` (see the crate docs), so a system
    /// whose answer that error could change entirely — `cond_∞ · ρ · accuracy ≥ 1` — is
    /// refused instead of returned. 0 (the default) trusts `F` to round-off.
    fn accuracy(&self) -> f64 {
        0.0
    }

    /// Whether a row of `F` that sums above 1 is integration error (eq. 15: `Σ_j F_ij ≤ 1`
    /// for form factors integrated per element pair, as in a dense matrix): then the excess
    /// enters `η`. An operator that hands each element its ancestor node's average (a
    /// hierarchy) has single rows above 1 by its discretisation error while its area-weighted
    /// sums stay exact; it returns false and only [`Operator::accuracy`] enters `η`.
    fn rows_bounded(&self) -> bool {
        true
    }
}

/// A dense `n × n` form-factor matrix borrowed as a row-major slice: `data[i * n + j] = F_ij`.
#[derive(Debug, Clone, Copy)]
pub struct DenseMatrix<'a> {
    n: usize,
    data: &'a [f64],
    accuracy: f64,
}

impl<'a> DenseMatrix<'a> {
    /// Wraps `data` (row-major, `data[i * n + j] = F_ij`). Checks `data.len() == n * n` and
    /// that every entry is finite.
    pub fn new(n: usize, data: &'a [f64]) -> Result<Self, SolveError> {
        let expected = n.checked_mul(n);
        if expected != Some(data.len()) {
            return Err(SolveError::MatrixSize { n, len: data.len() });
        }
        if let Some(k) = data.iter().position(|v| !v.is_finite()) {
            return Err(SolveError::NonFiniteFormFactor {
                row: k / n,
                col: k % n,
                value: data[k],
            });
        }
        Ok(Self {
            n,
            data,
            accuracy: 0.0,
        })
    }

    /// States the known accuracy of `F`'s row sums (see [`Operator::accuracy`]).
    pub fn with_accuracy(self, accuracy: f64) -> Self {
        Self {
            accuracy: accuracy.max(0.0),
            ..self
        }
    }

    /// Row `i` of `F`: `F_i0 .. F_i(n-1)`. Panics when `i >= n`.
    pub fn row(&self, i: usize) -> &'a [f64] {
        &self.data[i * self.n..(i + 1) * self.n]
    }

    /// The row-major entries.
    pub fn as_slice(&self) -> &'a [f64] {
        self.data
    }
}

/// `Σ_j row_j x_j`, summed sequentially in index order (deterministic).
fn dot(row: &[f64], x: &[f64]) -> f64 {
    let mut acc = 0.0;
    for (f, x) in row.iter().zip(x) {
        acc += f * x;
    }
    acc
}

impl Operator for DenseMatrix<'_> {
    fn accuracy(&self) -> f64 {
        self.accuracy
    }

    fn n(&self) -> usize {
        self.n
    }

    /// `y_i = Σ_j F_ij x_j`; rows in parallel when `n` is large, each row summed in index order,
    /// so the result does not depend on the thread count.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        assert_eq!(
            x.len(),
            self.n,
            "DenseMatrix::apply: x has the wrong length"
        );
        assert_eq!(
            y.len(),
            self.n,
            "DenseMatrix::apply: y has the wrong length"
        );
        let row = |(i, yi): (usize, &mut f64)| *yi = dot(self.row(i), x);
        if self.n >= PAR_MIN_ROWS {
            y.par_iter_mut().enumerate().with_min_len(16).for_each(row);
        } else {
            y.iter_mut().enumerate().for_each(row);
        }
    }

    /// One pass over `F` for the three bands; every band's sum is in index order, as in `apply`.
    fn apply_bands(&self, x: &[[f64; BANDS]], y: &mut [[f64; BANDS]]) {
        assert_eq!(
            x.len(),
            self.n,
            "DenseMatrix::apply_bands: x has the wrong length"
        );
        assert_eq!(
            y.len(),
            self.n,
            "DenseMatrix::apply_bands: y has the wrong length"
        );
        let row = |(i, yi): (usize, &mut [f64; BANDS])| {
            let mut acc = [0.0; BANDS];
            for (f, x) in self.row(i).iter().zip(x) {
                for c in 0..BANDS {
                    acc[c] += f * x[c];
                }
            }
            *yi = acc;
        };
        if self.n >= PAR_MIN_ROWS {
            y.par_iter_mut().enumerate().with_min_len(16).for_each(row);
        } else {
            y.iter_mut().enumerate().for_each(row);
        }
    }
}

/// Radiosities and how well they satisfy `(I − diag(ρ_c) F) b_c = e_c`.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Radiosity per element and band.
    pub b: Vec<[f64; BANDS]>,
    /// Per band: `‖(I − ρF) b − e‖₂ / ‖e‖₂` when `‖e‖₂ > 0`, else the absolute `‖(I − ρF) b − e‖₂`.
    pub residual: [f64; BANDS],
    /// Per band: whether `residual` is relative (`‖e‖₂ > 0`) or absolute.
    pub residual_relative: [bool; BANDS],
    /// Number of LU factorisations done (0 for [`solve_bounces`] and [`solve_iterative`];
    /// 1 for a grey scene).
    pub factorizations: usize,
    /// Per band: the estimate of `cond_∞(I − diag(ρ_c) F)` described in the crate docs (a lower
    /// bound, exact for physical operators). `None` when the band was not solved as a linear
    /// system: [`solve_bounces`], or a band without emission (`b = 0` is then exact) that shares
    /// no ρ with an emitting band.
    pub condition: [Option<f64>; BANDS],
    /// Per band: GMRES iterations (operator applications in the Arnoldi process) of
    /// [`solve_iterative`]; bands sharing one solve report the same count. 0 for the other
    /// solvers and for bands without emission.
    pub iterations: [u32; BANDS],
}

/// Why a solve was refused or failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SolveError {
    #[error("form-factor matrix has {len} entries, but n = {n} needs n * n")]
    MatrixSize { n: usize, len: usize },
    #[error("{what} has {len} entries, but the operator has n = {n} elements")]
    Length {
        what: &'static str,
        len: usize,
        n: usize,
    },
    #[error("form factor F[{row}][{col}] = {value} is not finite")]
    NonFiniteFormFactor { row: usize, col: usize, value: f64 },
    #[error(
        "reflectance of element {element}, band {band} is {value}: must be finite and in [0, 1]"
    )]
    Reflectance {
        element: usize,
        band: usize,
        value: f64,
    },
    #[error("emission of element {element}, band {band} is {value}: must be finite")]
    Emission {
        element: usize,
        band: usize,
        value: f64,
    },
    #[error(
        "the radiosity system (I - rho F) b = e of band {band} is singular or numerically singular: \
         no finite, meaningful solution exists (e.g. a closed scene whose surfaces all reflect \
         everything, rho = 1, with an emitter: light is never absorbed)"
    )]
    Singular { band: usize },
    #[error(
        "the bounce sum of band {band} became non-finite after {bounces} interreflections \
         (the operator amplifies light: check the form factors)"
    )]
    Diverged { band: usize, bounces: u32 },
    #[error(
        "the iterative solver did not converge in band {band}: relative residual {residual:.3e} \
         after {iterations} iterations, tolerance {tolerance:e} (raise the iteration budget or \
         the tolerance, or use the direct solver)"
    )]
    NotConverged {
        band: usize,
        iterations: u32,
        /// `‖(I − ρF) b − e‖₂ / ‖e‖₂` of the last iterate (which is not returned).
        residual: f64,
        tolerance: f64,
    },
    #[error("invalid iterative solver option: {0}")]
    InvalidOption(String),
    #[error("area of element {element} is {value}: must be finite and ≥ 0")]
    Area { element: usize, value: f64 },
}

/// Checks lengths and values of ρ and e against `n`.
fn check_inputs(n: usize, rho: &[[f64; BANDS]], e: &[[f64; BANDS]]) -> Result<(), SolveError> {
    for (what, len) in [("rho", rho.len()), ("e", e.len())] {
        if len != n {
            return Err(SolveError::Length { what, len, n });
        }
    }
    for (element, (r, e)) in rho.iter().zip(e).enumerate() {
        for band in 0..BANDS {
            let value = r[band];
            // `contains` is false for NaN; ±inf are outside [0, 1].
            if !(0.0..=1.0).contains(&value) {
                return Err(SolveError::Reflectance {
                    element,
                    band,
                    value,
                });
            }
            let value = e[band];
            if !value.is_finite() {
                return Err(SolveError::Emission {
                    element,
                    band,
                    value,
                });
            }
        }
    }
    Ok(())
}

/// Euclidean norm, summed in index order.
fn norm2(v: impl Iterator<Item = f64>) -> f64 {
    v.map(|x| x * x).sum::<f64>().sqrt()
}

/// Per band, the residual of eq. 7: `r = (I − diag(ρ) F) b − e = b − ρ ∘ (F b) − e`, reported as
/// `‖r‖₂ / ‖e‖₂` (flag `true`) when `‖e‖₂ > 0`, else as the absolute `‖r‖₂` (flag `false`).
/// Computed through the [`Operator`], so it serves both solvers.
pub fn residual<O: Operator + ?Sized>(
    op: &O,
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    b: &[[f64; BANDS]],
) -> Result<([f64; BANDS], [bool; BANDS]), SolveError> {
    let n = op.n();
    check_inputs(n, rho, e)?;
    if b.len() != n {
        return Err(SolveError::Length {
            what: "b",
            len: b.len(),
            n,
        });
    }
    let mut fb = vec![[0.0; BANDS]; n];
    op.apply_bands(b, &mut fb);
    let mut res = [0.0; BANDS];
    let mut relative = [false; BANDS];
    for c in 0..BANDS {
        let r = norm2((0..n).map(|i| b[i][c] - rho[i][c] * fb[i][c] - e[i][c]));
        let e_norm = norm2(e.iter().map(|e| e[c]));
        relative[c] = e_norm > 0.0;
        res[c] = if relative[c] { r / e_norm } else { r };
    }
    Ok((res, relative))
}

/// Band `c` of ρ (or e) as a column, for comparing bands.
fn column(v: &[[f64; BANDS]], c: usize) -> impl Iterator<Item = f64> + '_ {
    v.iter().map(move |x| x[c])
}

fn same_column(v: &[[f64; BANDS]], a: usize, b: usize) -> bool {
    column(v, a).eq(column(v, b))
}

/// The solves a scene needs: one job per distinct ρ column that some emitting band uses, as
/// `(first band of that ρ, right-hand sides)`; each right-hand side is a list of bands with the
/// same ρ and identical, nonzero e (solved once, copied to the others). Bands without emission
/// appear in no job: `b = 0` solves `A b = 0` exactly.
fn band_jobs(rho: &[[f64; BANDS]], e: &[[f64; BANDS]]) -> Vec<(usize, Vec<Vec<usize>>)> {
    // Bands with identical ρ: the same matrix A = I − diag(ρ_c) F.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for c in 0..BANDS {
        match groups.iter_mut().find(|g| same_column(rho, g[0], c)) {
            Some(g) => g.push(c),
            None => groups.push(vec![c]),
        }
    }
    groups
        .iter()
        .map(|group| {
            let mut rhs_bands: Vec<Vec<usize>> = Vec::new();
            for &c in group.iter().filter(|&&c| column(e, c).any(|v| v != 0.0)) {
                match rhs_bands.iter_mut().find(|r| same_column(e, r[0], c)) {
                    Some(r) => r.push(c),
                    None => rhs_bands.push(vec![c]),
                }
            }
            (group[0], rhs_bands)
        })
        .filter(|(_, rhs_bands)| !rhs_bands.is_empty())
        .collect()
}

/// `s_i = Σ_j F_ij` (the fraction of light leaving element `i` that lands on some element),
/// computed as `F 1` through the operator.
fn row_sums<O: Operator + ?Sized>(op: &O) -> Vec<f64> {
    let n = op.n();
    let mut s = vec![0.0; n];
    op.apply(&vec![1.0; n], &mut s);
    s
}

/// `η = max(n ε, max_i (ρ_i s_i − 1), max_i ρ_i · accuracy)`: the relative error of band `c`'s
/// operator. Physically `ρ_i s_i ≤ 1` (eq. 15: `s_i ≤ 1`), so a row reflecting more than all of
/// its light is integration error of at least that size; `accuracy` is what the producer of `F`
/// states about its row sums ([`Operator::accuracy`]).
///
/// For an operator whose rows are not bounded by 1 ([`Operator::rows_bounded`] false) only
/// `max_i ρ_i · accuracy` enters.
fn operator_error(
    rho: &[[f64; BANDS]],
    s: &[f64],
    c: usize,
    accuracy: f64,
    rows_bounded: bool,
) -> f64 {
    let excess = rho
        .iter()
        .zip(s)
        .map(|(r, s)| {
            let over = if rows_bounded { r[c] * s - 1.0 } else { 0.0 };
            over.max(r[c] * accuracy)
        })
        .fold(0.0f64, f64::max);
    (s.len() as f64 * f64::EPSILON).max(excess)
}

/// `cond_∞ · η ≥ 1` (or NaN): the relative error bound of `b` reaches 1, no digit is
/// guaranteed.
fn meaningless(condition: f64, eta: f64) -> bool {
    let bound = condition * eta;
    bound.is_nan() || bound >= 1.0
}

/// The condition estimate of one ρ group and the checks of the crate docs ("Condition estimate
/// and meaningless systems"): `z = A⁻¹ 1` (when solved) and the group's solutions `b` for
/// right-hand sides `e`. Returns `‖A‖∞ · max(‖z‖∞, max ‖b‖∞ / ‖e‖∞)`.
fn checked_condition(
    band: usize,
    norm_a: f64,
    eta: f64,
    z: Option<&[f64]>,
    solved: &[(&[f64], f64)],
) -> Result<f64, SolveError> {
    let max_abs = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let finite = z
        .iter()
        .chain(solved.iter().map(|(b, _)| b))
        .all(|v| v.iter().all(|x| x.is_finite()));
    if !finite {
        return Err(SolveError::Singular { band });
    }
    let mut inv_norm = 0.0f64;
    if let Some(z) = z {
        // z = Σ_k (ρF)^k 1 ≥ 1 for every system in which light decays.
        if z.iter().any(|&x| x < 0.5) {
            return Err(SolveError::Singular { band });
        }
        inv_norm = max_abs(z);
    }
    for &(b, e_max) in solved {
        if e_max > 0.0 {
            inv_norm = inv_norm.max(max_abs(b) / e_max);
        }
    }
    let condition = norm_a * inv_norm;
    if meaningless(condition, eta) {
        return Err(SolveError::Singular { band });
    }
    Ok(condition)
}

/// Solves `(I − diag(ρ_c) F) b_c = e_c` for the three bands by LU with partial pivoting (faer).
///
/// "No extra bands for a grey scene": bands whose ρ columns are identical share one
/// factorisation and are solved together as columns of one right-hand side; bands that also
/// share e are solved once and copied. A band with zero emission gets `b = 0` (an exact solution)
/// without being factored. [`Solution::factorizations`] counts the factorisations done.
///
/// Each factorisation also solves `A z = 1` (one more column) for [`Solution::condition`]. A
/// band is refused as [`SolveError::Singular`] when an LU pivot `|u_kk| ≤ n ε max|A|`, or by the
/// checks of the crate docs (non-finite solution, `min z < 1/2`, `cond_∞ · η ≥ 1`). NaN or
/// infinite values are never returned.
///
/// Each factorisation runs sequentially (`Par::Seq`), because faer 0.24's parallel LU gives
/// different bits for different thread counts; the distinct factorisations (up to three) run in
/// parallel on the current rayon pool instead. The result is bit-identical for any thread count.
/// Memory: one `n × n` matrix per distinct ρ band, alive at the same time.
pub fn solve_direct(
    f: &DenseMatrix,
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
) -> Result<Solution, SolveError> {
    let n = f.n;
    check_inputs(n, rho, e)?;
    let jobs = band_jobs(rho, e);
    let s = if jobs.is_empty() {
        Vec::new()
    } else {
        row_sums(f)
    };

    // One factorisation per job, in parallel; `collect` keeps job order, so the first error
    // reported is always the one of the lowest band.
    let solved: Vec<Result<(Mat<f64>, f64), SolveError>> = jobs
        .par_iter()
        .map(|(band, rhs_bands)| solve_band_group(f, rho, e, &s, *band, rhs_bands))
        .collect();

    let mut b = vec![[0.0; BANDS]; n];
    let mut condition = [None; BANDS];
    for ((band, rhs_bands), x) in jobs.iter().zip(solved) {
        let (x, cond) = x?;
        for (k, bands) in rhs_bands.iter().enumerate() {
            for &c in bands {
                for (bi, v) in b.iter_mut().zip(x.col_as_slice(k)) {
                    bi[c] = *v;
                }
            }
        }
        for c in (0..BANDS).filter(|&c| same_column(rho, *band, c)) {
            condition[c] = Some(cond);
        }
    }

    let (residual, residual_relative) = residual(f, rho, e, &b)?;
    Ok(Solution {
        b,
        residual,
        residual_relative,
        factorizations: jobs.len(),
        condition,
        iterations: [0; BANDS],
    })
}

/// Factors `A = I − diag(ρ_band) F` once and solves it for one right-hand side column per entry
/// of `rhs_bands` (the e column of that entry's first band), plus `A z = 1` in the last column.
/// Returns the `n × (k + 1)` solutions and the group's condition estimate.
fn solve_band_group(
    f: &DenseMatrix,
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    s: &[f64],
    band: usize,
    rhs_bands: &[Vec<usize>],
) -> Result<(Mat<f64>, f64), SolveError> {
    let n = f.n;
    let k = rhs_bands.len();
    let (a, max_abs) = system_matrix(f, rho, band);
    let mut x = Mat::from_fn(n, k + 1, |i, col| {
        if col < k {
            e[i][rhs_bands[col][0]]
        } else {
            1.0
        }
    });
    lu_solve(a, x.as_mut(), max_abs).map_err(|()| SolveError::Singular { band })?;

    let solved: Vec<(&[f64], f64)> = rhs_bands
        .iter()
        .enumerate()
        .map(|(col, bands)| {
            let e_max = column(e, bands[0]).fold(0.0f64, |m, v| m.max(v.abs()));
            (x.col_as_slice(col), e_max)
        })
        .collect();
    let eta = operator_error(rho, s, band, f.accuracy(), f.rows_bounded());
    let condition = checked_condition(
        band,
        infinity_norm(f, rho, band),
        eta,
        Some(x.col_as_slice(k)),
        &solved,
    )?;
    Ok((x, condition))
}

/// `A = I − diag(ρ_c) F` (eq. 7's matrix for band `c`), column-major for faer, and `max |A_ij|`.
fn system_matrix(f: &DenseMatrix, rho: &[[f64; BANDS]], c: usize) -> (Mat<f64>, f64) {
    let n = f.n;
    let mut max_abs = 0.0f64;
    let a = Mat::from_fn(n, n, |i, j| {
        let delta = if i == j { 1.0 } else { 0.0 };
        let v = delta - rho[i][c] * f.data[i * n + j];
        max_abs = max_abs.max(v.abs());
        v
    });
    (a, max_abs)
}

/// `‖I − diag(ρ_c) F‖∞` (largest absolute row sum).
fn infinity_norm(f: &DenseMatrix, rho: &[[f64; BANDS]], c: usize) -> f64 {
    (0..f.n)
        .map(|i| {
            f.row(i)
                .iter()
                .enumerate()
                .map(|(j, v)| ((if i == j { 1.0 } else { 0.0 }) - rho[i][c] * v).abs())
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

/// Factors `a = P⁻¹ L U` in place (partial pivoting) and overwrites `x` with `a⁻¹ x`.
/// Fails when a pivot is at most `n ε max_abs` (numerically singular).
fn lu_solve(mut a: Mat<f64>, x: faer::MatMut<'_, f64>, max_abs: f64) -> Result<(), ()> {
    let n = a.nrows();
    // Sequential: faer's parallel LU is not bit-identical across thread counts.
    let par = Par::Seq;
    let mut perm = vec![0usize; n];
    let mut perm_inv = vec![0usize; n];
    let mut mem = MemBuffer::new(
        factor::lu_in_place_scratch::<usize, f64>(n, n, par, Default::default()).or(
            solve::solve_in_place_scratch::<usize, f64>(n, x.ncols(), par),
        ),
    );
    let (_, p) = factor::lu_in_place(
        a.as_mut(),
        &mut perm,
        &mut perm_inv,
        par,
        MemStack::new(&mut mem),
        Default::default(),
    );
    let tol = n as f64 * f64::EPSILON * max_abs;
    // A NaN pivot (from a non-finite input) counts as singular too.
    if (0..n).any(|k| a[(k, k)].is_nan() || a[(k, k)].abs() <= tol) {
        return Err(());
    }
    // The unit lower factor L sits below the diagonal of `a`, U on and above it; each triangular
    // solve reads only its own triangle.
    let lu: MatRef<'_, f64> = a.as_ref();
    solve::solve_in_place_with_conj(lu, lu, p, Conj::No, x, par, MemStack::new(&mut mem));
    Ok(())
}

/// The Neumann series of eq. 7 truncated after exactly `k` interreflections:
/// `b = Σ_{m=0}^{k+1} (ρF)^m e`, computed as `b⁰ = e`, `b^{m+1} = e + ρ ∘ (F b^m)`, `k + 1` times.
/// `k = 0` is direct light only, `b = e + ρ (F e)` (the paper's Figure 7 progression).
///
/// Uses only `y = F x`, so any [`Operator`] works. Bit-identical for any rayon thread count
/// when the operator is (as [`DenseMatrix`] is). [`Solution::factorizations`] is 0.
pub fn solve_bounces<O: Operator + ?Sized>(
    op: &O,
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    k: u32,
) -> Result<Solution, SolveError> {
    let n = op.n();
    check_inputs(n, rho, e)?;
    let mut b = e.to_vec();
    let mut fb = vec![[0.0; BANDS]; n];
    for m in 0..=k {
        op.apply_bands(&b, &mut fb);
        for i in 0..n {
            for c in 0..BANDS {
                b[i][c] = e[i][c] + rho[i][c] * fb[i][c];
            }
        }
        // Stop at the first bounce that overflows, never return inf/NaN.
        if let Some(band) = (0..BANDS).find(|&c| !column(&b, c).all(f64::is_finite)) {
            return Err(SolveError::Diverged { band, bounces: m });
        }
    }
    let (residual, residual_relative) = residual(op, rho, e, &b)?;
    Ok(Solution {
        b,
        residual,
        residual_relative,
        factorizations: 0,
        condition: [None; BANDS],
        iterations: [0; BANDS],
    })
}
