//! Energy balance: emitted = absorbed + escaped for solved systems with reciprocal form
//! factors, checked by hand, on closed and open scenes, and shown to expose unsolved systems
//! and non-reciprocal form factors.

mod common;

use bake_solver::{
    energy_balance, solve_bounces, solve_direct, solve_iterative, DenseMatrix, EnergyBalance,
    IterativeOptions, SolveError, BANDS,
};
use common::*;

#[test]
fn two_elements_by_hand() {
    // Areas 1 and 2, A_1 F_12 = A_2 F_21 = 0.4: F_12 = 0.4, F_21 = 0.2 (open: rows 0.4, 0.2).
    // ρ = 1/2, e = (1, 0): b_1 = 1 + 0.2 b_2, b_2 = 0.1 b_1 → b_1 = 1/0.98, b_2 = 0.1/0.98.
    // H_1 = 0.4 b_2, H_2 = 0.2 b_1; absorbed = 1·½·0.04/0.98 + 2·½·0.2/0.98 = 0.22/0.98;
    // escaped = 1·b_1·0.6 + 2·b_2·0.8 = 0.76/0.98; emitted = 1 = (0.22 + 0.76)/0.98.
    let f = [0.0, 0.4, 0.2, 0.0];
    let f = DenseMatrix::new(2, &f).unwrap();
    let area = [1.0, 2.0];
    let rho = [[0.5; 3]; 2];
    let e = [[1.0, 0.0, 1.0], [0.0; 3]];
    let s = solve_direct(&f, &rho, &e).unwrap();
    let balance = energy_balance(&f, &area, &rho, &e, &s.b).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-15;
    for c in [0, 2] {
        assert!(close(balance.emitted[c], 1.0));
        assert!(close(balance.absorbed[c], 0.22 / 0.98), "{balance:?}");
        assert!(close(balance.escaped[c], 0.76 / 0.98), "{balance:?}");
        assert!(balance.imbalance[c] < 1e-15);
        assert!(balance.imbalance_relative[c]);
    }
    // Band 1 is dark: everything 0, imbalance absolute.
    assert_eq!(
        (balance.emitted[1], balance.absorbed[1], balance.escaped[1]),
        (0.0, 0.0, 0.0)
    );
    assert_eq!(balance.imbalance[1], 0.0);
    assert!(!balance.imbalance_relative[1]);
}

fn check(name: &str, balance: &EnergyBalance, open: bool) {
    for c in 0..BANDS {
        eprintln!(
            "{name} band {c}: emitted {:.6e}, absorbed {:.6e}, escaped {:.6e}, imbalance {:.1e}",
            balance.emitted[c], balance.absorbed[c], balance.escaped[c], balance.imbalance[c]
        );
        assert!(balance.imbalance_relative[c]);
        assert!(balance.imbalance[c] < 1e-11, "{name}: {balance:?}");
        let escaped = balance.escaped[c] / balance.emitted[c];
        if open {
            assert!(escaped > 0.01, "{name}: {balance:?}");
        } else {
            assert!(escaped.abs() < 1e-12, "{name}: {balance:?}");
        }
    }
}

#[test]
fn closed_and_open_scenes_balance() {
    let n = 120;
    for open in [false, true] {
        let (f, area) = reciprocal_form_factors(n, 40, open);
        let f = DenseMatrix::new(n, &f).unwrap();
        for rho in [0.5, 0.9, 0.99, 0.999, 0.9999] {
            let rho = uniform(n, [rho, 0.7 * rho, 0.3]);
            let mut e = uniform(n, [0.0; 3]);
            e[0] = [1.0; 3];
            e[17] = [0.5, 2.0, 1.0];
            let direct = solve_direct(&f, &rho, &e).unwrap();
            let name = format!("open {open}, ρ {:?}", rho[0]);
            check(
                &format!("{name} direct"),
                &energy_balance(&f, &area, &rho, &e, &direct.b).unwrap(),
                open,
            );
            let iterative = solve_iterative(&f, &rho, &e, &IterativeOptions::default()).unwrap();
            check(
                &format!("{name} iterative"),
                &energy_balance(&f, &area, &rho, &e, &iterative.b).unwrap(),
                open,
            );
        }
    }
}

#[test]
fn unsolved_systems_and_non_reciprocal_form_factors_show() {
    let n = 60;
    let (f, area) = reciprocal_form_factors(n, 41, false);
    let f = DenseMatrix::new(n, &f).unwrap();
    let rho = uniform(n, [0.8; 3]);
    let mut e = uniform(n, [0.0; 3]);
    e[5] = [1.0; 3];
    // Truncated bounces: light still in flight is neither absorbed nor escaped; the imbalance
    // shrinks by about ρ per bounce.
    let imbalance = |k| {
        let b = solve_bounces(&f, &rho, &e, k).unwrap().b;
        energy_balance(&f, &area, &rho, &e, &b).unwrap().imbalance[0]
    };
    let (i2, i4) = (imbalance(2), imbalance(4));
    eprintln!("bounces: K = 2 imbalance {i2:.3e}, K = 4 {i4:.3e}");
    assert!(
        i2 > 0.1 && i4 < i2 * 0.8 * 0.8 * 1.1 && i4 > 0.01,
        "{i2} {i4}"
    );

    // Rows normalised to 1 without reciprocity: the books do not balance.
    let f = closed_form_factors(n, 42);
    let f = DenseMatrix::new(n, &f).unwrap();
    let b = solve_direct(&f, &rho, &e).unwrap().b;
    let balance = energy_balance(&f, &area, &rho, &e, &b).unwrap();
    eprintln!("non-reciprocal: imbalance {:.3e}", balance.imbalance[0]);
    assert!(balance.imbalance[0] > 1e-3, "{balance:?}");
}

#[test]
fn bad_inputs_are_errors() {
    let f = [0.0, 0.5, 0.5, 0.0];
    let f = DenseMatrix::new(2, &f).unwrap();
    let ok = [[0.5; 3]; 2];
    assert_eq!(
        energy_balance(&f, &[1.0], &ok, &ok, &ok),
        Err(SolveError::Length {
            what: "area",
            len: 1,
            n: 2
        })
    );
    assert!(matches!(
        energy_balance(&f, &[1.0, 1.0], &ok, &ok, &ok[..1]),
        Err(SolveError::Length { what: "b", .. })
    ));
    for value in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            energy_balance(&f, &[1.0, value], &ok, &ok, &ok),
            Err(SolveError::Area { element: 1, .. })
        ));
    }
    let mut rho = ok;
    rho[1][0] = 2.0;
    assert!(matches!(
        energy_balance(&f, &[1.0, 1.0], &rho, &ok, &ok),
        Err(SolveError::Reflectance { .. })
    ));
}
