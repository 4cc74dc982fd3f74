//! `--max-error E`: from a target on the relative error of `b` to the per-pair form-factor
//! tolerance that guarantees it, before anything is integrated.
//!
//! The estimator `auto` keeps every pair's relative error within τ, so each row of `F` sums to
//! at most `1 + τ` and is off by at most `τ` of its sum: `‖δ(ρF)‖∞ ≤ ρ_max τ`. For such rows
//! `‖A‖∞ ≤ 1 + ρ_max(1 + τ)` and `‖A⁻¹‖∞ ≤ 1/(1 − ρ_max(1 + τ))` (the Neumann series of
//! `A = I − diag(ρ)F`), so
//!
//! ```text
//! cond∞(A) ≤ (1 + ρ_max(1 + τ)) / (1 − ρ_max(1 + τ))
//! ```
//!
//! and the relative error of `b` is about `cond∞ · ρ_max · τ` (the solver's `η` is
//! `ρ_max · accuracy`). [`pair_tolerance`] is the largest τ for which that product meets E,
//! in closed form (a quadratic in `ρ_max τ`), capped at E itself: `F` reaches the irradiance
//! `H = F b` of a lightmap without the solve's amplification. After the solve the condition
//! estimate of the actual matrix replaces the bound ([`Accuracy::error_bound`]).
//!
//! This module does not integrate anything and knows no geometry: it sees ρ_max and E only.

use crate::error::ErrorSummary;
use serde::{Deserialize, Serialize};
use solver::BANDS;

/// The a-priori bound on `cond∞(I − diag(ρ)F)` for rows of `F` that sum to at most `1 + τ`;
/// infinite when `ρ_max (1 + τ) ≥ 1` (light need not decay: no bound).
pub fn condition_bound(rho_max: f64, tau: f64) -> f64 {
    let r = rho_max * (1.0 + tau);
    if r >= 1.0 {
        f64::INFINITY
    } else {
        (1.0 + r) / (1.0 - r)
    }
}

/// The largest per-pair relative tolerance τ ≤ E with
/// `condition_bound(ρ_max, τ) · ρ_max · τ ≤ E`; 0 when `ρ_max ≥ 1` (no tolerance bounds the
/// error: the contour integral, the most accurate estimator, is the best there is).
///
/// With `u = ρ_max τ` the condition is `u² + (1 + ρ + E) u − E (1 − ρ) ≤ 0`, whose positive root
/// is taken in the cancellation-free form `2E(1 − ρ) / ((1 + ρ + E) + √((1 + ρ + E)² + 4E(1 − ρ)))`.
pub fn pair_tolerance(max_error: f64, rho_max: f64) -> f64 {
    if rho_max >= 1.0 {
        return 0.0;
    }
    if rho_max <= 0.0 {
        return max_error;
    }
    let (e, r) = (max_error, rho_max);
    let p = 1.0 + r + e;
    let u = 2.0 * e * (1.0 - r) / (p + (p * p + 4.0 * e * (1.0 - r)).sqrt());
    (u / r).min(max_error)
}

/// What the target asked for and what the bake could promise: the report's `accuracy` object.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Accuracy {
    /// The target relative error of `b` (`--max-error`, or the preset's).
    pub max_error: f64,
    /// The largest reflectance of any element in any band.
    pub rho_max: f64,
    /// The per-pair tolerance the target chose for `auto` (`None` when an explicit estimator
    /// or `--ff-tolerance` decided it, or the transport was not the dense one).
    pub ff_tolerance: Option<f64>,
    /// Hierarchical transport: the link tolerance (ε over the mean radiosity) its last linking
    /// pass ran with, derived from `max_error` unless `--link-tolerance` set it, and the
    /// amplification `B̄ / Ē` that pass's coarse solve measured (absent on other transports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link_tolerance: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplification: Option<f64>,
    /// The row-sum accuracy the solver was told (what the estimator states).
    pub row_sum_accuracy: f64,
    /// [`condition_bound`] for ρ_max and that accuracy (`None`: unbounded, ρ_max = 1).
    pub condition_bound: Option<f64>,
    /// Per band after the solve: the solver's condition estimate × ρ_max × the row-sum
    /// accuracy, the bound on the relative error of `b` that the form factors' accuracy
    /// leaves (`None` where the band was not solved as a linear system, or unbounded).
    pub error_bound: [Option<f64>; BANDS],
    /// Dense transport: rows of F past 1 and what was done about them
    /// ([`form_factor::DenseFormFactors::limit_row_sums`]); `None` on other transports (and
    /// absent from the report then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub row_sums: Option<RowSums>,
    /// The elements' error estimates summarised ([`crate::error::summary`]; absent in older
    /// reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorSummary>,
}

/// The dense transport's row sums Σ_j F_ij, before and after rows past 1 were scaled to 1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RowSums {
    /// The largest row sum as integrated.
    pub largest_before: f64,
    /// The largest row sum the solver was given (≤ 1 up to rounding).
    pub largest_after: f64,
    /// Rows that summed past 1 and were scaled to 1.
    pub scaled: usize,
    /// Of those, rows past 1 + [`crate::ROW_SUM_WARNING_MARGIN`] (or the row-sum accuracy,
    /// when larger): surfaces seen twice, not integration or sampling error (the bake warns,
    /// naming their polygons).
    pub seen_twice: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tolerance meets the target with equality (below the cap) and no larger one does.
    #[test]
    fn the_tolerance_meets_the_target_exactly() {
        for e in [1e-2, 1e-3, 1e-4, 1e-6] {
            for rho in [0.3, 0.5, 0.9, 0.99, 0.999, 0.9999, 1.0 - 6e-8] {
                let tau = pair_tolerance(e, rho);
                let achieved = condition_bound(rho, tau) * rho * tau;
                assert!(achieved <= e * (1.0 + 1e-12), "{e} {rho}: {achieved}");
                if tau < e {
                    // 1 − ρ(1 + τ) keeps ~8 digits for ρ = 1 − 6e-8 (the largest f32 below 1).
                    assert!((achieved / e - 1.0).abs() < 1e-7, "{e} {rho}: {achieved}");
                    let more = tau * (1.0 + 1e-6);
                    assert!(condition_bound(rho, more) * rho * more > e);
                }
            }
        }
    }

    /// Closed form against the leading-order behaviour `τ ≈ E (1 − ρ) / (ρ (1 + ρ))` as ρ → 1,
    /// and the end cases.
    #[test]
    fn tolerances_near_one_and_at_the_ends() {
        for rho in [0.999, 0.9999, 0.99999] {
            let tau = pair_tolerance(1e-3, rho);
            let approx = 1e-3 * (1.0 - rho) / (rho * (1.0 + rho));
            assert!(
                (tau / approx - 1.0).abs() < 2e-3,
                "{rho}: {tau} vs {approx}"
            );
        }
        assert_eq!(pair_tolerance(1e-3, 1.0), 0.0);
        assert_eq!(pair_tolerance(1e-3, 0.0), 1e-3);
        // Small ρ: the cap (F's own error reaches H unamplified).
        assert_eq!(pair_tolerance(1e-3, 0.1), 1e-3);
        assert_eq!(condition_bound(1.0, 0.0), f64::INFINITY);
        assert_eq!(condition_bound(0.5, 0.0), 3.0);
    }
}
