//! Conservation of energy for a solved scene.
//!
//! With radiosity `b_i` (power leaving element `i` per unit area, in the paper's intensity
//! unit) and the incident light of eq. 5 `H_i = Σ_j F_ij b_j` (by reciprocity `A_i F_ij =
//! A_j F_ji`, the power arriving at `i` per unit area), per band:
//!
//! ```text
//! emitted  = Σ_i A_i e_i
//! absorbed = Σ_i A_i (1 − ρ_i) H_i                 (what element i keeps of what reaches it)
//! escaped  = Σ_i A_i b_i (1 − Σ_j F_ij)            (leaves i and reaches no element: openings)
//! ```
//!
//! and `emitted = absorbed + escaped` for any `b` that solves eq. 7 (`b_i = e_i + ρ_i H_i`)
//! with reciprocal form factors, because
//!
//! ```text
//! emitted − absorbed − escaped = Σ_i A_i (e_i + ρ_i H_i − b_i) + Σ_ij (A_i F_ij b_i − A_i F_ij b_j)
//! ```
//!
//! where the first sum is the area-weighted residual and the second is zero by reciprocity. A
//! large imbalance thus means an unsolved system or non-reciprocal form factors.

use crate::{check_inputs, row_sums, Operator, SolveError, BANDS};

/// Per-band power balance of a solution (see the module docs for the formulas).
#[derive(Debug, Clone, PartialEq)]
pub struct EnergyBalance {
    /// `Σ A_i e_i`.
    pub emitted: [f64; BANDS],
    /// `Σ A_i (1 − ρ_i) H_i`, `H = F b`.
    pub absorbed: [f64; BANDS],
    /// `Σ A_i b_i (1 − Σ_j F_ij)`: light leaving through openings.
    pub escaped: [f64; BANDS],
    /// `|emitted − absorbed − escaped| / emitted`, or the absolute difference when
    /// `emitted = 0` (see `imbalance_relative`).
    pub imbalance: [f64; BANDS],
    /// Per band: whether `imbalance` is relative (`emitted > 0`) or absolute.
    pub imbalance_relative: [bool; BANDS],
}

/// The energy balance of radiosities `b` in a scene with form factors `op`, element areas
/// `area`, reflectances `rho` and emission `e`. Pure linear algebra: two operator applications
/// (`F b` for three bands, `F 1`) and sums in index order, so deterministic whenever the
/// operator is. Checks lengths and values like the solvers; areas must be finite and ≥ 0.
pub fn energy_balance<O: Operator + ?Sized>(
    op: &O,
    area: &[f64],
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    b: &[[f64; BANDS]],
) -> Result<EnergyBalance, SolveError> {
    let n = op.n();
    check_inputs(n, rho, e)?;
    for (what, len) in [("area", area.len()), ("b", b.len())] {
        if len != n {
            return Err(SolveError::Length { what, len, n });
        }
    }
    if let Some((element, &value)) = area
        .iter()
        .enumerate()
        .find(|(_, a)| !(a.is_finite() && **a >= 0.0))
    {
        return Err(SolveError::Area { element, value });
    }
    // H = F b (eq. 5) and s = F 1.
    let mut h = vec![[0.0; BANDS]; n];
    op.apply_bands(b, &mut h);
    let s = row_sums(op);

    let mut balance = EnergyBalance {
        emitted: [0.0; BANDS],
        absorbed: [0.0; BANDS],
        escaped: [0.0; BANDS],
        imbalance: [0.0; BANDS],
        imbalance_relative: [false; BANDS],
    };
    for c in 0..BANDS {
        let (mut emitted, mut absorbed, mut escaped) = (0.0, 0.0, 0.0);
        for i in 0..n {
            emitted += area[i] * e[i][c];
            absorbed += area[i] * (1.0 - rho[i][c]) * h[i][c];
            escaped += area[i] * b[i][c] * (1.0 - s[i]);
        }
        let difference = (emitted - absorbed - escaped).abs();
        balance.emitted[c] = emitted;
        balance.absorbed[c] = absorbed;
        balance.escaped[c] = escaped;
        balance.imbalance_relative[c] = emitted != 0.0;
        balance.imbalance[c] = if emitted != 0.0 {
            difference / emitted.abs()
        } else {
            difference
        };
    }
    Ok(balance)
}
