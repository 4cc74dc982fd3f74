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
//!
//! With light arriving from outside the elements (punctual lights: an external irradiance
//! `H⁰_i`, in the same unit as `H`), the system is `b_i = e_i + ρ_i (H_i + H⁰_i)` and
//! [`energy_balance_lit`] counts `delivered = Σ_i A_i H⁰_i`, absorbs
//! `Σ_i A_i (1 − ρ_i)(H_i + H⁰_i)` (the first hit included) and checks
//! `delivered + emitted = absorbed + escaped`.

use crate::{check_inputs, row_sums, Operator, SolveError, BANDS};

/// Per-band power balance of a solution (see the module docs for the formulas); the bake
/// report's `energy` object.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EnergyBalance {
    /// `Σ A_i H⁰_i`: external light (punctual lights) arriving at the elements (absent in
    /// older reports: 0).
    #[cfg_attr(feature = "serde", serde(default))]
    pub delivered: [f64; BANDS],
    /// `Σ A_i e_i`.
    pub emitted: [f64; BANDS],
    /// `Σ A_i (1 − ρ_i) (H_i + H⁰_i)`, `H = F b`.
    pub absorbed: [f64; BANDS],
    /// `Σ A_i b_i (1 − Σ_j F_ij)`: light leaving through openings.
    pub escaped: [f64; BANDS],
    /// `|delivered + emitted − absorbed − escaped| / (delivered + emitted)`, or the absolute
    /// difference when nothing enters (see `imbalance_relative`).
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
    energy_balance_lit(op, area, rho, e, &vec![[0.0; BANDS]; op.n()], b)
}

/// [`energy_balance`] for `b = e + ρ (F b + H⁰)`: `external` is `H⁰` per element (see the
/// module docs).
pub fn energy_balance_lit<O: Operator + ?Sized>(
    op: &O,
    area: &[f64],
    rho: &[[f64; BANDS]],
    e: &[[f64; BANDS]],
    external: &[[f64; BANDS]],
    b: &[[f64; BANDS]],
) -> Result<EnergyBalance, SolveError> {
    let n = op.n();
    check_inputs(n, rho, e)?;
    if external.len() != n {
        return Err(SolveError::Length {
            what: "external irradiance",
            len: external.len(),
            n,
        });
    }
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
        delivered: [0.0; BANDS],
        emitted: [0.0; BANDS],
        absorbed: [0.0; BANDS],
        escaped: [0.0; BANDS],
        imbalance: [0.0; BANDS],
        imbalance_relative: [false; BANDS],
    };
    for c in 0..BANDS {
        let (mut delivered, mut emitted, mut absorbed, mut escaped) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            delivered += area[i] * external[i][c];
            emitted += area[i] * e[i][c];
            absorbed += area[i] * (1.0 - rho[i][c]) * (h[i][c] + external[i][c]);
            escaped += area[i] * b[i][c] * (1.0 - s[i]);
        }
        let entered = delivered + emitted;
        let difference = (entered - absorbed - escaped).abs();
        balance.delivered[c] = delivered;
        balance.emitted[c] = emitted;
        balance.absorbed[c] = absorbed;
        balance.escaped[c] = escaped;
        balance.imbalance_relative[c] = entered != 0.0;
        balance.imbalance[c] = if entered != 0.0 {
            difference / entered.abs()
        } else {
            difference
        };
    }
    Ok(balance)
}
