//! Restarted GMRES (Saad & Schultz 1986) on eq. 7, `(I − diag(ρ_c) F) b_c = e_c`, through
//! [`Operator::apply`] only.
//!
//! Why GMRES: the Jacobi/Gauss–Seidel sweeps behind [`crate::solve_bounces`] contract by about
//! the spectral radius of `ρF`, which is ρ in a closed scene (rows of F sum to 1), so ρ = 0.9999
//! needs ~10⁵ sweeps per digit group. The spectrum of `A = I − ρF` is instead a cluster around 1
//! (the form-factor operator is compact-like: most eigenvalues of F are small) plus a few
//! outliers down to `1 − ρ`; a Krylov method removes each outlier in a few iterations, whatever
//! ρ is. GMRES needs only `y = F x` (no transpose, no symmetry: a hierarchical operator need
//! not be exactly reciprocal) and minimises the residual, which is what the tolerance is about.
//!
//! Numerics: Arnoldi with modified Gram–Schmidt run twice ("twice is enough"), so the basis stays
//! orthogonal to working precision and the residual can reach ~1e-15; Givens rotations for the
//! small least-squares problem. The implicit residual only decides when to leave a cycle early:
//! convergence is always judged on the true residual `‖(I − ρF) b − e‖₂ / ‖e‖₂` recomputed from
//! `b` exactly as [`crate::residual`] computes it, so a returned solution meets the tolerance.
//!
//! Determinism: every dot product and norm is summed sequentially in index order, and the
//! operator's `apply` is deterministic ([`crate::DenseMatrix`] is), so the result is
//! bit-identical for any rayon thread count.

use crate::{
    band_jobs, check_inputs, checked_condition, meaningless, norm2, operator_error, residual,
    row_sums, same_column, Operator, Solution, SolveError, BANDS,
};
use rayon::prelude::*;

/// Settings of [`solve_iterative`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterativeOptions {
    /// Stop when the relative residual `‖(I − ρF) b − e‖₂ / ‖e‖₂` of a band is at most this.
    /// In (0, 1). The forward error is at most about `cond_∞ · tolerance`.
    ///
    /// Rounding puts a floor of roughly `ε ‖A‖ ‖b‖ / ‖e‖ ≤ ε cond` (times up to `√n`) under
    /// the computed residual of any solver. For a closed scene with ρ = 0.9999 (cond ≈ 2·10⁴)
    /// that is close to the default: on a 213-element box GMRES reached 9.6e-13 while the
    /// direct solver's LU answer has 4.8e-12. Brighter or larger scenes can stop at the floor
    /// and fail with [`SolveError::NotConverged`] unless the tolerance is raised.
    pub tolerance: f64,
    /// Budget of GMRES iterations (operator applications in the Arnoldi process; the true
    /// residual recomputed at each restart is not counted) per right-hand side.
    pub max_iterations: u32,
    /// Restart length m of GMRES(m): Krylov vectors kept (memory `(m + 1) n` values per solve).
    pub restart: u32,
    /// Whether to solve `A z = 1` for [`Solution::condition`] (about as many iterations
    /// again). Without it the condition is the lower bound `‖A‖∞ ‖b‖∞ / ‖e‖∞`: for
    /// intermediate solves whose answer only steers further work (a hierarchy's linking
    /// passes), not for a bake's result.
    pub condition: bool,
}

impl Default for IterativeOptions {
    /// Tolerance 1e-12, 1000 iterations, restart 100 (the Gram–Schmidt work per iteration,
    /// ≤ 4 · 100 · n flops, stays below one dense `apply`, 2n², from n = 200 on).
    fn default() -> Self {
        IterativeOptions {
            tolerance: 1e-12,
            max_iterations: 1000,
            restart: 100,
            condition: true,
        }
    }
}

/// Tolerance of the extra solve `A z = 1` behind [`Solution::condition`] (at least the user's):
/// a condition estimate needs a few digits, not twelve.
const CONDITION_TOLERANCE: f64 = 1e-8;

/// Solves `(I − diag(ρ_c) F) b_c = e_c` for the three bands by restarted GMRES, using only
/// `y = F x` ([`Operator::apply`]), so any operator works.
///
/// Per band the iteration stops when the true relative residual is at most
/// `options.tolerance` (absolute when `e_c = 0`, which is solved exactly by `b = 0` without
/// iterating). When the budget `options.max_iterations` runs out first, the result is
/// [`SolveError::NotConverged`] naming the band, the iterations and the residual reached: an
/// unconverged iterate is never returned.
///
/// Sharing as in [`crate::solve_direct`]: bands with identical ρ and e are solved once and
/// copied (a grey scene is one solve). For [`Solution::condition`] each distinct ρ column of an
/// emitting band also solves `A z = 1` (to `max(tolerance, 1e-8)`, same budget); a band is
/// refused as [`SolveError::Singular`] by the checks of the crate docs, and already during the
/// iteration when the iterate grows so large that `‖A‖∞ ‖b‖∞ / ‖A b‖∞ · η ≥ 1` (a lower bound
/// on `cond_∞ · η`: no digit can be right). If the condition solve itself does not converge,
/// the estimate falls back to the lower bound `‖A‖∞ ‖b‖∞ / ‖e‖∞`.
///
/// `‖A‖∞` is taken as `max_i (1 + ρ_i Σ_j F_ij)`, exact for `F ≥ 0` with `F_ii = 0` (the
/// form-factor invariants). Solves of different bands run in parallel; the result is
/// bit-identical for any thread count. [`Solution::factorizations`] is 0 and
/// [`Solution::iterations`] holds each band's GMRES iterations.
pub fn solve_iterative<O: Operator + ?Sized>(
    op: &O,
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    options: &IterativeOptions,
) -> Result<Solution, SolveError> {
    let n = op.n();
    check_inputs(n, rho, e)?;
    check_options(options)?;
    let jobs = band_jobs(rho, e);
    let s = if jobs.is_empty() {
        Vec::new()
    } else {
        row_sums(op)
    };

    // One task per ρ group: its right-hand sides, then the condition solve, in order.
    let solved: Vec<Result<GroupResult, SolveError>> = jobs
        .par_iter()
        .map(|(band, rhs_bands)| solve_group(op, rho, e, &s, *band, rhs_bands, options))
        .collect();

    let mut b = vec![[0.0; BANDS]; n];
    let mut condition = [None; BANDS];
    let mut iterations = [0; BANDS];
    for ((band, rhs_bands), group) in jobs.iter().zip(solved) {
        let group = group?;
        for (bands, (x, its)) in rhs_bands.iter().zip(&group.solutions) {
            for &c in bands {
                for (bi, v) in b.iter_mut().zip(x) {
                    bi[c] = *v;
                }
                iterations[c] = *its;
            }
        }
        for c in (0..BANDS).filter(|&c| same_column(rho, *band, c)) {
            condition[c] = Some(group.condition);
        }
    }

    let (residual, residual_relative) = residual(op, rho, e, &b)?;
    Ok(Solution {
        b,
        residual,
        residual_relative,
        factorizations: 0,
        condition,
        iterations,
    })
}

fn check_options(options: &IterativeOptions) -> Result<(), SolveError> {
    let t = options.tolerance;
    if !(t > 0.0 && t < 1.0) {
        return Err(SolveError::InvalidOption(format!(
            "tolerance must be in (0, 1), got {t}"
        )));
    }
    if options.restart == 0 {
        return Err(SolveError::InvalidOption(
            "restart length must be at least 1".to_string(),
        ));
    }
    Ok(())
}

/// The solutions of one ρ group (one per right-hand side, with its iteration count) and the
/// group's condition estimate.
struct GroupResult {
    solutions: Vec<(Vec<f64>, u32)>,
    condition: f64,
}

/// Solves band group `band`'s right-hand sides (first band of each entry of `rhs_bands`), then
/// `A z = 1`, and runs the checks of the crate docs.
fn solve_group<O: Operator + ?Sized>(
    op: &O,
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    s: &[f64],
    band: usize,
    rhs_bands: &[Vec<usize>],
    options: &IterativeOptions,
) -> Result<GroupResult, SolveError> {
    let system = System {
        op,
        rho: rho.iter().map(|r| r[band]).collect(),
        // ‖A‖∞ = max_i (|1 − ρ_i F_ii| + ρ_i Σ_{j≠i} |F_ij|) = max_i (1 + ρ_i s_i) for F ≥ 0,
        // F_ii = 0.
        norm_a: rho
            .iter()
            .zip(s)
            .map(|(r, s)| 1.0 + r[band] * s.abs())
            .fold(0.0f64, f64::max),
        eta: operator_error(rho, s, band, op.accuracy(), op.rows_bounded()),
    };
    let mut solutions = Vec::with_capacity(rhs_bands.len());
    for bands in rhs_bands {
        let c = bands[0];
        let rhs: Vec<f64> = e.iter().map(|e| e[c]).collect();
        match system.gmres(&rhs, options.tolerance, options) {
            Ok(solved) => solutions.push(solved),
            Err(Failure::Singular) => return Err(SolveError::Singular { band: c }),
            Err(Failure::NotConverged {
                iterations,
                residual,
            }) => {
                return Err(SolveError::NotConverged {
                    band: c,
                    iterations,
                    residual,
                    tolerance: options.tolerance,
                })
            }
        }
    }

    let z = if options.condition {
        let ones = vec![1.0; e.len()];
        match system.gmres(&ones, options.tolerance.max(CONDITION_TOLERANCE), options) {
            Ok((z, _)) => Some(z),
            Err(Failure::Singular) => return Err(SolveError::Singular { band }),
            Err(Failure::NotConverged { .. }) => None,
        }
    } else {
        None
    };
    let solved: Vec<(&[f64], f64)> = rhs_bands
        .iter()
        .zip(&solutions)
        .map(|(bands, (x, _))| {
            let e_max = e.iter().fold(0.0f64, |m, e| m.max(e[bands[0]].abs()));
            (x.as_slice(), e_max)
        })
        .collect();
    let condition = checked_condition(band, system.norm_a, system.eta, z.as_deref(), &solved)?;
    Ok(GroupResult {
        solutions,
        condition,
    })
}

/// Why one GMRES solve stopped without a solution.
enum Failure {
    NotConverged { iterations: u32, residual: f64 },
    Singular,
}

/// `A = I − diag(ρ) F` for one band, with `‖A‖∞` and the visible operator error `η`.
struct System<'a, O: ?Sized> {
    op: &'a O,
    rho: Vec<f64>,
    norm_a: f64,
    eta: f64,
}

impl<O: Operator + ?Sized> System<'_, O> {
    /// `y = A x = x − ρ ∘ (F x)`.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.op.apply(x, y);
        for ((y, x), r) in y.iter_mut().zip(x).zip(&self.rho) {
            *y = x - r * *y;
        }
    }

    /// `d = A x − rhs`, computed as `x_i − ρ_i (F x)_i − rhs_i` (the very arithmetic of
    /// [`crate::residual`]); returns `‖d‖₂` and `‖A x‖∞`.
    fn residual(&self, x: &[f64], rhs: &[f64], d: &mut [f64]) -> (f64, f64) {
        self.op.apply(x, d);
        let mut ax_max = 0.0f64;
        for (((d, x), r), rhs) in d.iter_mut().zip(x).zip(&self.rho).zip(rhs) {
            let ax = x - r * *d;
            ax_max = ax_max.max(ax.abs());
            *d = x - r * *d - rhs;
        }
        (norm2(d.iter().copied()), ax_max)
    }

    /// GMRES(m) from `x = 0` until `‖A x − rhs‖₂ ≤ tolerance ‖rhs‖₂`. Returns `x` and the
    /// iterations used.
    fn gmres(
        &self,
        rhs: &[f64],
        tolerance: f64,
        options: &IterativeOptions,
    ) -> Result<(Vec<f64>, u32), Failure> {
        let n = rhs.len();
        let rhs_norm = norm2(rhs.iter().copied());
        let mut x = vec![0.0; n];
        if rhs_norm == 0.0 {
            return Ok((x, 0));
        }
        let target = tolerance * rhs_norm;
        let restart = options.restart as usize;
        // r = rhs − A x = rhs at x = 0.
        let mut r = rhs.to_vec();
        let mut beta = rhs_norm;
        let mut iterations = 0u32;
        let mut d = vec![0.0; n];
        loop {
            if beta <= target {
                return Ok((x, iterations));
            }
            if iterations >= options.max_iterations {
                return Err(Failure::NotConverged {
                    iterations,
                    residual: beta / rhs_norm,
                });
            }
            let m = restart.min((options.max_iterations - iterations) as usize);
            let (y, basis, used) = self.arnoldi(&r, beta, m, target)?;
            iterations += used as u32;
            // x += V y.
            for (yj, v) in y.iter().zip(&basis) {
                for (x, v) in x.iter_mut().zip(v) {
                    *x += yj * v;
                }
            }
            // The true residual, never the implicit one.
            let (norm, ax_max) = self.residual(&x, rhs, &mut d);
            if !norm.is_finite() || !x.iter().all(|v| v.is_finite()) {
                return Err(Failure::Singular);
            }
            // cond_∞ ≥ ‖A‖∞ ‖x‖∞ / ‖A x‖∞; with η that bounds the attainable relative error.
            let x_max = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if ax_max > 0.0 && meaningless(self.norm_a * x_max / ax_max, self.eta) {
                return Err(Failure::Singular);
            }
            beta = norm;
            for (r, d) in r.iter_mut().zip(&d) {
                *r = -d;
            }
        }
    }

    /// One GMRES cycle of at most `m` Arnoldi steps from `r` (`‖r‖₂ = beta`): returns the
    /// least-squares coefficients `y`, the Krylov basis `V` they multiply, and the steps taken.
    /// Leaves early when the implicit residual reaches `target` or the Krylov space is
    /// invariant (breakdown).
    #[allow(clippy::type_complexity)]
    fn arnoldi(
        &self,
        r: &[f64],
        beta: f64,
        m: usize,
        target: f64,
    ) -> Result<(Vec<f64>, Vec<Vec<f64>>, usize), Failure> {
        let n = r.len();
        let mut basis: Vec<Vec<f64>> = Vec::with_capacity(m + 1);
        basis.push(r.iter().map(|v| v / beta).collect());
        // Column j of the rotated Hessenberg matrix: R's column j (length j + 1).
        let mut h: Vec<Vec<f64>> = Vec::with_capacity(m);
        let (mut cs, mut sn): (Vec<f64>, Vec<f64>) = (Vec::with_capacity(m), Vec::with_capacity(m));
        // g = Qᵀ β e₁; |g[k]| is the implicit residual after k steps.
        let mut g = vec![0.0; m + 1];
        g[0] = beta;
        let mut k = 0;
        while k < m {
            let mut w = vec![0.0; n];
            self.apply(&basis[k], &mut w);
            let w_norm = norm2(w.iter().copied());
            let mut col = vec![0.0; k + 2];
            // Modified Gram–Schmidt, twice.
            for _ in 0..2 {
                for (i, v) in basis.iter().enumerate() {
                    let hij = dot(v, &w);
                    for (w, v) in w.iter_mut().zip(v) {
                        *w -= hij * v;
                    }
                    col[i] += hij;
                }
            }
            let h_next = norm2(w.iter().copied());
            col[k + 1] = h_next;
            // Earlier rotations, then the one that zeroes col[k + 1].
            for i in 0..k {
                let t = cs[i] * col[i] + sn[i] * col[i + 1];
                col[i + 1] = -sn[i] * col[i] + cs[i] * col[i + 1];
                col[i] = t;
            }
            let (c, s) = givens(col[k], col[k + 1]);
            col[k] = c * col[k] + s * col[k + 1];
            col.truncate(k + 1);
            g[k + 1] = -s * g[k];
            g[k] *= c;
            h.push(col);
            cs.push(c);
            sn.push(s);
            k += 1;
            // Breakdown (A maps the Krylov space into itself: the cycle's answer is exact), or
            // NaN from the operator (caught as non-finite by the caller).
            if h_next.is_nan() || h_next <= f64::EPSILON * w_norm || g[k].abs() <= target {
                break;
            }
            if k < m {
                basis.push(w.iter().map(|w| w / h_next).collect());
            }
        }
        // Back substitution R y = g.
        let mut y = vec![0.0; k];
        for i in (0..k).rev() {
            let mut acc = g[i];
            for (j, yj) in y.iter().enumerate().skip(i + 1) {
                acc -= h[j][i] * yj;
            }
            if h[i][i] == 0.0 {
                // A singular on the Krylov space: no least-squares solution improves x.
                return Err(Failure::Singular);
            }
            y[i] = acc / h[i][i];
        }
        basis.truncate(k);
        Ok((y, basis, k))
    }
}

/// `Σ_i a_i b_i`, in index order.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = 0.0;
    for (a, b) in a.iter().zip(b) {
        acc += a * b;
    }
    acc
}

/// The rotation `(c, s)` with `c a + s b = √(a² + b²)` and `−s a + c b = 0`.
fn givens(a: f64, b: f64) -> (f64, f64) {
    let r = a.hypot(b);
    if r == 0.0 {
        (1.0, 0.0)
    } else {
        (a / r, b / r)
    }
}
