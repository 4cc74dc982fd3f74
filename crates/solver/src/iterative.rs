//! Restarted GMRES (Saad & Schultz 1986) on eq. 7, `(I − diag(ρ_c) F) b_c = e_c`, through
//! the operator's products only ([`Operator::apply`], [`Operator::apply_bands`]).
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
//! Lockstep: the solves of all bands (then all condition solves) advance together, one
//! operator product each per step, fused into one [`Operator::apply_bands`] (a hierarchical
//! operator's pass over its links costs little more for three bands than for one). Each
//! solve's arithmetic is that of a solve on its own.
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
/// form-factor invariants). Solves of different bands run in lockstep (module docs); the result is
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

    // Every ρ group's right-hand sides, then every group's condition solve, each phase as
    // GMRES lanes in lockstep: one fused `apply_bands` per step serves up to three solves.
    let solved = solve_groups(op, rho, e, &s, &jobs, options);
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

/// Solves each band group's right-hand sides (first band of each entry of its `rhs_bands`),
/// then its `A z = 1`, and runs the checks of the crate docs; one result per group, in order.
/// The solves of one phase run as lanes of [`run_lanes`], so each lane's arithmetic is that
/// of a solve of its own (bit for bit: `apply_bands` gives the bits of `apply`).
fn solve_groups<O: Operator + ?Sized>(
    op: &O,
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    s: &[f64],
    jobs: &[(usize, Vec<Vec<usize>>)],
    options: &IterativeOptions,
) -> Vec<Result<GroupResult, SolveError>> {
    let systems: Vec<System> = jobs
        .iter()
        .map(|(band, _)| System {
            rho: rho.iter().map(|r| r[*band]).collect(),
            // ‖A‖∞ = max_i (|1 − ρ_i F_ii| + ρ_i Σ_{j≠i} |F_ij|) = max_i (1 + ρ_i s_i) for
            // F ≥ 0, F_ii = 0.
            norm_a: rho
                .iter()
                .zip(s)
                .map(|(r, s)| 1.0 + r[*band] * s.abs())
                .fold(0.0f64, f64::max),
            eta: operator_error(rho, s, *band, op.accuracy(), op.rows_bounded()),
        })
        .collect();
    // Phase 1: every right-hand side of every group.
    let mut lanes = Vec::new();
    for (g, (_, rhs_bands)) in jobs.iter().enumerate() {
        for bands in rhs_bands {
            let rhs: Vec<f64> = e.iter().map(|e| e[bands[0]]).collect();
            lanes.push(Lane::new(g, rhs, options.tolerance));
        }
    }
    let solved = run_lanes(op, &systems, lanes, options);
    // Phase 2: the condition solves of the groups whose solves all succeeded.
    let mut per_group: Vec<Vec<Solved>> = jobs.iter().map(|_| Vec::new()).collect();
    for (lane, result) in solved {
        per_group[lane.group].push(result);
    }
    let failed = |g: usize| per_group[g].iter().any(|r| r.is_err());
    let condition_lanes: Vec<Lane> = if options.condition {
        (0..jobs.len())
            .filter(|&g| !failed(g))
            .map(|g| {
                let tolerance = options.tolerance.max(CONDITION_TOLERANCE);
                Lane::new(g, vec![1.0; e.len()], tolerance)
            })
            .collect()
    } else {
        Vec::new()
    };
    let mut z: Vec<Option<Result<Vec<f64>, Failure>>> = jobs.iter().map(|_| None).collect();
    for (lane, result) in run_lanes(op, &systems, condition_lanes, options) {
        z[lane.group] = Some(result.map(|(z, _)| z));
    }
    jobs.iter()
        .zip(per_group)
        .zip(z)
        .zip(&systems)
        .map(|((((band, rhs_bands), results), z), system)| {
            let mut solutions = Vec::with_capacity(results.len());
            for (bands, result) in rhs_bands.iter().zip(results) {
                let c = bands[0];
                match result {
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
            let z = match z {
                Some(Ok(z)) => Some(z),
                Some(Err(Failure::Singular)) => return Err(SolveError::Singular { band: *band }),
                Some(Err(Failure::NotConverged { .. })) | None => None,
            };
            let solved: Vec<(&[f64], f64)> = rhs_bands
                .iter()
                .zip(&solutions)
                .map(|(bands, (x, _))| {
                    let e_max = e.iter().fold(0.0f64, |m, e| m.max(e[bands[0]].abs()));
                    (x.as_slice(), e_max)
                })
                .collect();
            let condition =
                checked_condition(*band, system.norm_a, system.eta, z.as_deref(), &solved)?;
            Ok(GroupResult {
                solutions,
                condition,
            })
        })
        .collect()
}

/// Runs GMRES lanes to the end in lockstep: each step, the vectors that the lanes still
/// running need multiplied by F go through one `apply_bands` (one `apply` when a single lane
/// is left), then every lane takes its product. Returns each lane with its result, in order.
fn run_lanes<O: Operator + ?Sized>(
    op: &O,
    systems: &[System],
    mut lanes: Vec<Lane>,
    options: &IterativeOptions,
) -> Vec<(Lane, Solved)> {
    let n = op.n();
    for lane in &mut lanes {
        lane.start_cycle(options);
    }
    let mut x = vec![[0.0; BANDS]; n];
    let mut y = vec![[0.0; BANDS]; n];
    let mut single = vec![0.0; n];
    loop {
        let running: Vec<usize> = (0..lanes.len())
            .filter(|&k| lanes[k].request().is_some())
            .collect();
        if running.is_empty() {
            break;
        }
        for batch in running.chunks(BANDS) {
            if let [k] = batch {
                let v = lanes[*k].request().unwrap_or(&[]);
                op.apply(v, &mut single);
                let group = lanes[*k].group;
                lanes[*k].receive(&systems[group], &single, options);
                continue;
            }
            for (slot, &k) in batch.iter().enumerate() {
                let v = lanes[k].request().unwrap_or(&[]);
                for (xi, v) in x.iter_mut().zip(v) {
                    xi[slot] = *v;
                }
            }
            for xi in &mut x {
                xi[batch.len()..].fill(0.0);
            }
            op.apply_bands(&x, &mut y);
            let taken: Vec<(&mut Lane, usize)> = lanes
                .iter_mut()
                .enumerate()
                .filter_map(|(k, lane)| batch.iter().position(|&b| b == k).map(|slot| (lane, slot)))
                .collect();
            taken.into_par_iter().for_each(|(lane, slot)| {
                let fx: Vec<f64> = y.iter().map(|v| v[slot]).collect();
                lane.receive(&systems[lane.group], &fx, options);
            });
        }
    }
    lanes
        .into_iter()
        .map(|mut lane| {
            let result = lane.result.take().unwrap_or(Err(Failure::Singular));
            (lane, result)
        })
        .collect()
}

/// What one GMRES solve returns: its solution and iterations, or why it stopped without one.
type Solved = Result<(Vec<f64>, u32), Failure>;

/// Why one GMRES solve stopped without a solution.
enum Failure {
    NotConverged { iterations: u32, residual: f64 },
    Singular,
}

/// `A = I − diag(ρ) F` for one band, with `‖A‖∞` and the visible operator error `η`.
struct System {
    rho: Vec<f64>,
    norm_a: f64,
    eta: f64,
}

/// Where a [`Lane`] is.
enum Phase {
    /// In a GMRES cycle: the next product is `F v_k` of the Krylov basis.
    Arnoldi,
    /// After a cycle: the next product is `F x`, for the true residual.
    Residual,
    /// Finished: [`Lane::result`] is set.
    Done,
}

/// One restarted GMRES(m) solve `A x = rhs` from `x = 0` (until `‖A x − rhs‖₂ ≤ tolerance
/// ‖rhs‖₂`), written as a state machine that asks for one product `F v` at a time
/// ([`Lane::request`], [`Lane::receive`]) so that several solves can share each operator
/// pass. The arithmetic is the plain algorithm's, in the same order.
struct Lane {
    /// The band group whose system this lane solves.
    group: usize,
    rhs: Vec<f64>,
    rhs_norm: f64,
    target: f64,
    x: Vec<f64>,
    r: Vec<f64>,
    beta: f64,
    iterations: u32,
    phase: Phase,
    result: Option<Solved>,
    // The current cycle: at most `m` Arnoldi steps.
    m: usize,
    k: usize,
    basis: Vec<Vec<f64>>,
    /// Column j of the rotated Hessenberg matrix: R's column j (length j + 1).
    h: Vec<Vec<f64>>,
    cs: Vec<f64>,
    sn: Vec<f64>,
    /// `Qᵀ β e₁`; `|g[k]|` is the implicit residual after k steps.
    g: Vec<f64>,
}

impl Lane {
    fn new(group: usize, rhs: Vec<f64>, tolerance: f64) -> Lane {
        let n = rhs.len();
        let rhs_norm = norm2(rhs.iter().copied());
        Lane {
            group,
            rhs_norm,
            target: tolerance * rhs_norm,
            x: vec![0.0; n],
            // r = rhs − A x = rhs at x = 0.
            r: rhs.clone(),
            rhs,
            beta: rhs_norm,
            iterations: 0,
            phase: Phase::Residual,
            result: None,
            m: 0,
            k: 0,
            basis: Vec::new(),
            h: Vec::new(),
            cs: Vec::new(),
            sn: Vec::new(),
            g: Vec::new(),
        }
    }

    fn finish(&mut self, result: Result<(), Failure>) {
        let x = std::mem::take(&mut self.x);
        self.result = Some(result.map(|()| (x, self.iterations)));
        self.phase = Phase::Done;
        self.basis = Vec::new();
    }

    /// The top of the restart loop: done, out of budget, or a new cycle from `r`.
    fn start_cycle(&mut self, options: &IterativeOptions) {
        if self.rhs_norm == 0.0 || self.beta <= self.target {
            return self.finish(Ok(()));
        }
        if self.iterations >= options.max_iterations {
            let failure = Failure::NotConverged {
                iterations: self.iterations,
                residual: self.beta / self.rhs_norm,
            };
            self.phase = Phase::Done;
            self.result = Some(Err(failure));
            return;
        }
        self.m =
            (options.restart as usize).min((options.max_iterations - self.iterations) as usize);
        self.basis = Vec::with_capacity(self.m + 1);
        let beta = self.beta;
        self.basis.push(self.r.iter().map(|v| v / beta).collect());
        self.h = Vec::with_capacity(self.m);
        self.cs = Vec::with_capacity(self.m);
        self.sn = Vec::with_capacity(self.m);
        self.g = vec![0.0; self.m + 1];
        self.g[0] = beta;
        self.k = 0;
        self.phase = Phase::Arnoldi;
    }

    /// The vector whose product with F the lane needs next; `None` once it is done.
    fn request(&self) -> Option<&[f64]> {
        match self.phase {
            Phase::Arnoldi => Some(&self.basis[self.k]),
            Phase::Residual => Some(&self.x),
            Phase::Done => None,
        }
    }

    /// Takes `fx = F v` for the vector of [`Lane::request`] and moves on.
    fn receive(&mut self, system: &System, fx: &[f64], options: &IterativeOptions) {
        match self.phase {
            Phase::Arnoldi => self.arnoldi_step(system, fx),
            Phase::Residual => self.residual_step(system, fx, options),
            Phase::Done => {}
        }
    }

    /// One Arnoldi step with `w = A v_k = v_k − ρ ∘ (F v_k)`; at the cycle's end (m steps,
    /// the implicit residual at the target, or breakdown) x takes the cycle's correction and
    /// the lane asks for the true residual.
    fn arnoldi_step(&mut self, system: &System, fx: &[f64]) {
        let k = self.k;
        let mut w: Vec<f64> = fx.to_vec();
        for ((w, v), r) in w.iter_mut().zip(&self.basis[k]).zip(&system.rho) {
            *w = v - r * *w;
        }
        let w_norm = norm2(w.iter().copied());
        let mut col = vec![0.0; k + 2];
        // Modified Gram–Schmidt, twice.
        for _ in 0..2 {
            for (i, v) in self.basis.iter().enumerate() {
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
            let t = self.cs[i] * col[i] + self.sn[i] * col[i + 1];
            col[i + 1] = -self.sn[i] * col[i] + self.cs[i] * col[i + 1];
            col[i] = t;
        }
        let (c, s) = givens(col[k], col[k + 1]);
        col[k] = c * col[k] + s * col[k + 1];
        col.truncate(k + 1);
        self.g[k + 1] = -s * self.g[k];
        self.g[k] *= c;
        self.h.push(col);
        self.cs.push(c);
        self.sn.push(s);
        self.k = k + 1;
        let k = self.k;
        // Breakdown (A maps the Krylov space into itself: the cycle's answer is exact), or
        // NaN from the operator (caught as non-finite below).
        let end = h_next.is_nan()
            || h_next <= f64::EPSILON * w_norm
            || self.g[k].abs() <= self.target
            || k >= self.m;
        if !end {
            self.basis.push(w.iter().map(|w| w / h_next).collect());
            return;
        }
        // Back substitution R y = g.
        let mut y = vec![0.0; k];
        for i in (0..k).rev() {
            let mut acc = self.g[i];
            for (j, yj) in y.iter().enumerate().skip(i + 1) {
                acc -= self.h[j][i] * yj;
            }
            if self.h[i][i] == 0.0 {
                // A singular on the Krylov space: no least-squares solution improves x.
                return self.finish(Err(Failure::Singular));
            }
            y[i] = acc / self.h[i][i];
        }
        self.iterations += k as u32;
        // x += V y.
        for (yj, v) in y.iter().zip(&self.basis) {
            for (x, v) in self.x.iter_mut().zip(v) {
                *x += yj * v;
            }
        }
        self.basis = Vec::new();
        self.phase = Phase::Residual;
    }

    /// The true residual `d = A x − rhs`, computed as `x_i − ρ_i (F x)_i − rhs_i` (the very
    /// arithmetic of [`crate::residual`]), never the implicit one; then the restart loop's
    /// checks.
    fn residual_step(&mut self, system: &System, fx: &[f64], options: &IterativeOptions) {
        let mut d: Vec<f64> = fx.to_vec();
        let mut ax_max = 0.0f64;
        for (((d, x), r), rhs) in d.iter_mut().zip(&self.x).zip(&system.rho).zip(&self.rhs) {
            let ax = x - r * *d;
            ax_max = ax_max.max(ax.abs());
            *d = x - r * *d - rhs;
        }
        let norm = norm2(d.iter().copied());
        if !norm.is_finite() || !self.x.iter().all(|v| v.is_finite()) {
            return self.finish(Err(Failure::Singular));
        }
        // cond_∞ ≥ ‖A‖∞ ‖x‖∞ / ‖A x‖∞; with η that bounds the attainable relative error.
        let x_max = self.x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if ax_max > 0.0 && meaningless(system.norm_a * x_max / ax_max, system.eta) {
            return self.finish(Err(Failure::Singular));
        }
        self.beta = norm;
        for (r, d) in self.r.iter_mut().zip(&d) {
            *r = -d;
        }
        self.start_cycle(options);
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
