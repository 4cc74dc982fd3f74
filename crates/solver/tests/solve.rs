//! Tests of the radiosity solvers against hand-solved systems and closed-form identities.

use bake_solver::{
    residual, solve_bounces, solve_direct, DenseMatrix, Operator, Solution, SolveError, BANDS,
};

mod common;

use common::{bits, closed_form_factors, coloured_scene, max_rel_diff, uniform};

#[test]
fn two_by_two_solved_by_hand() {
    // F = [[0, 0.8], [0.4, 0]].
    let f = [0.0, 0.8, 0.4, 0.0];
    let f = DenseMatrix::new(2, &f).unwrap();
    // Band 0: ρ = (0.5, 0.5), e = (1, 0): b1 = 1 + 0.4 b2, b2 = 0.2 b1 → b1 = 1/0.92, b2 = 0.2/0.92.
    // Band 1: ρ = (1, 0.25), e = (0, 2): b1 = 0.8 b2, b2 = 2 + 0.1 b1 → b2 = 2/0.92, b1 = 1.6/0.92.
    // Band 2: ρ = 0: b = e = (3, 4).
    let rho = [[0.5, 1.0, 0.0], [0.5, 0.25, 0.0]];
    let e = [[1.0, 0.0, 3.0], [0.0, 2.0, 4.0]];
    let s = solve_direct(&f, &rho, &e).unwrap();
    let want = [[1.0 / 0.92, 1.6 / 0.92, 3.0], [0.2 / 0.92, 2.0 / 0.92, 4.0]];
    for (got, want) in s.b.iter().flatten().zip(want.iter().flatten()) {
        assert!((got - want).abs() <= 1e-15 * want.abs(), "{got} vs {want}");
    }
    assert_eq!(s.factorizations, 3);
    assert_eq!(s.residual_relative, [true; 3]);
    assert!(s.residual.iter().all(|&r| r < 1e-15), "{:?}", s.residual);
}

#[test]
fn furnace_gives_one_over_one_minus_rho() {
    // Rows sum to 1, uniform ρ, e = 1: b = e + ρ b (every row) → b = 1/(1 − ρ).
    let n = 60;
    let f = closed_form_factors(n, 1);
    let f = DenseMatrix::new(n, &f).unwrap();
    let e = uniform(n, [1.0; 3]);
    let rhos = [0.5, 0.9, 0.99];
    let check = |s: &Solution, rho: [f64; 3]| {
        for bi in &s.b {
            for c in 0..BANDS {
                let want = 1.0 / (1.0 - rho[c]);
                assert!(
                    (bi[c] - want).abs() <= 1e-10 * want,
                    "ρ = {}: {}",
                    rho[c],
                    bi[c]
                );
            }
        }
    };
    // Coloured: one band per ρ.
    let s = solve_direct(&f, &uniform(n, rhos), &e).unwrap();
    assert_eq!(s.factorizations, 3);
    check(&s, rhos);
    // Grey, each ρ on its own.
    for rho in rhos {
        let s = solve_direct(&f, &uniform(n, [rho; 3]), &e).unwrap();
        assert_eq!(s.factorizations, 1);
        check(&s, [rho; 3]);
    }
}

#[test]
fn zero_bounces_is_direct_light_exactly() {
    // K = 0: b = e + ρ (F e), with F e summed in index order: bit for bit.
    let n = 200; // above the parallel-rows threshold
    let f = closed_form_factors(n, 2);
    let (rho, e) = coloured_scene(n, 3);
    let op = DenseMatrix::new(n, &f).unwrap();
    let s = solve_bounces(&op, &rho, &e, 0).unwrap();
    assert_eq!(s.factorizations, 0);
    for i in 0..n {
        for c in 0..BANDS {
            let mut fe = 0.0;
            for j in 0..n {
                fe += f[i * n + j] * e[j][c];
            }
            assert_eq!(s.b[i][c].to_bits(), (e[i][c] + rho[i][c] * fe).to_bits());
        }
    }
}

#[test]
fn bounces_converge_to_the_direct_solve() {
    let n = 80;
    let f = closed_form_factors(n, 4);
    let f = DenseMatrix::new(n, &f).unwrap();
    let rho = uniform(n, [0.5; 3]);
    let mut e = uniform(n, [0.0; 3]);
    e[0] = [1.0, 1.0, 1.0];
    e[5] = [0.0, 3.0, 0.5];
    let exact = solve_direct(&f, &rho, &e).unwrap();
    let err = |k| max_rel_diff(&solve_bounces(&f, &rho, &e, k).unwrap().b, &exact.b);
    // The truncation error Σ_{m ≥ K+2} (ρF)^m e shrinks by ρ = 0.5 per bounce here (rows of F
    // sum to 1, so the dominant eigenvalue of ρF is ρ), until round-off.
    let errors: Vec<f64> = (0..30).map(err).collect();
    assert!(
        errors[0] > 1e-3,
        "K = 0 should still miss the interreflections"
    );
    for k in 1..errors.len() {
        let ratio = errors[k] / errors[k - 1];
        assert!((0.45..0.55).contains(&ratio), "K = {k}: {errors:?}");
    }
    assert!(err(200) < 1e-8, "K = 200: {}", err(200));
}

#[test]
fn grey_scene_is_factored_once_coloured_three_times() {
    let n = 50;
    let f = closed_form_factors(n, 5);
    let f = DenseMatrix::new(n, &f).unwrap();
    let (rho_col, e_col) = coloured_scene(n, 6);
    let grey_rho: Vec<[f64; 3]> = rho_col.iter().map(|r| [r[0]; 3]).collect();
    let grey_e: Vec<[f64; 3]> = e_col.iter().map(|e| [e[0]; 3]).collect();

    // Grey ρ and grey e: one factorisation, one solve, copied.
    let s = solve_direct(&f, &grey_rho, &grey_e).unwrap();
    assert_eq!(s.factorizations, 1);
    assert!(s.b.iter().all(|b| b[0] == b[1] && b[1] == b[2]));

    // Grey ρ, coloured e: still one factorisation (three right-hand sides).
    let s = solve_direct(&f, &grey_rho, &e_col).unwrap();
    assert_eq!(s.factorizations, 1);
    assert!(s.residual.iter().all(|&r| r < 1e-12), "{:?}", s.residual);
    // Equal to solving each band on its own.
    for c in 0..BANDS {
        let e_c: Vec<[f64; 3]> = e_col.iter().map(|e| [e[c]; 3]).collect();
        let alone = solve_direct(&f, &grey_rho, &e_c).unwrap();
        for (a, b) in alone.b.iter().zip(&s.b) {
            assert!((a[0] - b[c]).abs() <= 1e-13 * a[0].abs().max(1.0));
        }
    }

    // Two bands share ρ: two factorisations.
    let two: Vec<[f64; 3]> = rho_col.iter().map(|r| [r[0], r[1], r[0]]).collect();
    assert_eq!(solve_direct(&f, &two, &e_col).unwrap().factorizations, 2);

    // Coloured: three.
    let s = solve_direct(&f, &rho_col, &e_col).unwrap();
    assert_eq!(s.factorizations, 3);
}

#[test]
fn singular_systems_are_errors() {
    // Exactly singular: two elements that see only each other, ρ = 1: A = [[1, -1], [-1, 1]].
    let f = [0.0, 1.0, 1.0, 0.0];
    let f = DenseMatrix::new(2, &f).unwrap();
    let rho = [[1.0, 0.5, 0.5]; 2];
    let e = [[1.0; 3], [0.0; 3]];
    assert_eq!(
        solve_direct(&f, &rho, &e),
        Err(SolveError::Singular { band: 0 })
    );

    // Closed box (rows sum to 1 up to round-off), ρ = 1 everywhere in band 1, an emitter:
    // light is never absorbed; singular to working precision.
    let n = 40;
    let f = closed_form_factors(n, 7);
    let f = DenseMatrix::new(n, &f).unwrap();
    let rho = uniform(n, [0.6, 1.0, 0.6]);
    let mut e = uniform(n, [0.0; 3]);
    e[3] = [1.0; 3];
    let err = solve_direct(&f, &rho, &e).unwrap_err();
    assert_eq!(err, SolveError::Singular { band: 1 });
    assert!(err.to_string().contains("singular"), "{err}");

    // Grey ρ = 1: the shared factorisation reports the first band.
    let rho = uniform(n, [1.0; 3]);
    assert_eq!(
        solve_direct(&f, &rho, &e),
        Err(SolveError::Singular { band: 0 })
    );
}

#[test]
fn a_stated_form_factor_accuracy_refuses_leaky_rho_one_boxes() {
    // Rows that fall 1e-10 short of 1 (integration error of a closed box) with ρ = 1: the
    // operator alone looks like a slightly leaky box (cond ≈ 1e10) and would be "solved".
    let n = 40;
    let mut f = closed_form_factors(n, 11);
    for v in &mut f {
        *v *= 1.0 - 1e-10;
    }
    let rho = uniform(n, [1.0; 3]);
    let mut e = uniform(n, [0.0; 3]);
    e[0] = [1.0; 3];
    let trusting = DenseMatrix::new(n, &f).unwrap();
    assert!(solve_direct(&trusting, &rho, &e).is_ok());
    // Stating that row sums are only good to 1e-9 makes every digit of that answer doubtful.
    let stated = trusting.with_accuracy(1e-9);
    assert_eq!(
        solve_direct(&stated, &rho, &e),
        Err(SolveError::Singular { band: 0 })
    );
    // The same statement leaves a well-posed furnace (ρ = 0.9999, cond ≈ 2e4) alone.
    let rho = uniform(n, [0.9999; 3]);
    let b = solve_direct(&stated, &rho, &e).unwrap().b;
    assert!(b.iter().all(|x| x[0].is_finite() && x[0] > 0.0));
}

#[test]
fn zero_emission_gives_zero_radiosity() {
    let n = 30;
    let f = closed_form_factors(n, 8);
    let f = DenseMatrix::new(n, &f).unwrap();
    let (rho, _) = coloured_scene(n, 9);
    let e = uniform(n, [0.0; 3]);
    for s in [
        solve_direct(&f, &rho, &e).unwrap(),
        solve_bounces(&f, &rho, &e, 5).unwrap(),
    ] {
        assert!(s.b.iter().flatten().all(|&v| v == 0.0));
        assert_eq!(s.residual, [0.0; 3]);
        assert_eq!(s.residual_relative, [false; 3]);
        assert_eq!(s.factorizations, 0);
    }
    // b = 0 is an exact solution even of a singular system.
    let s = solve_direct(&f, &uniform(n, [1.0; 3]), &e).unwrap();
    assert!(s.b.iter().flatten().all(|&v| v == 0.0));
}

#[test]
fn direct_residual_is_tiny() {
    let n = 300;
    let f = closed_form_factors(n, 10);
    let f = DenseMatrix::new(n, &f).unwrap();
    let (rho, e) = coloured_scene(n, 11);
    let s = solve_direct(&f, &rho, &e).unwrap();
    assert_eq!(s.residual_relative, [true; 3]);
    assert!(s.residual.iter().all(|&r| r < 1e-12), "{:?}", s.residual);
    // The public residual function agrees with the reported one.
    assert_eq!(
        residual(&f, &rho, &e, &s.b).unwrap(),
        (s.residual, [true; 3])
    );
    // And a wrong b has a large residual.
    let wrong: Vec<[f64; 3]> = s.b.iter().map(|b| [b[0] * 1.1, b[1], b[2]]).collect();
    let (r, _) = residual(&f, &rho, &e, &wrong).unwrap();
    assert!(r[0] > 1e-3 && r[1] < 1e-12);
}

#[test]
fn bad_inputs_are_errors() {
    let f = [0.0, 0.5, 0.5, 0.0];
    assert_eq!(
        DenseMatrix::new(3, &f).unwrap_err(),
        SolveError::MatrixSize { n: 3, len: 4 }
    );
    assert!(DenseMatrix::new(usize::MAX, &f).is_err()); // n * n overflows
    let bad = [0.0, f64::NAN, 0.5, 0.0];
    assert!(matches!(
        DenseMatrix::new(2, &bad),
        Err(SolveError::NonFiniteFormFactor { row: 0, col: 1, .. })
    ));

    let f = DenseMatrix::new(2, &f).unwrap();
    let ok = [[0.5; 3]; 2];
    assert_eq!(
        solve_direct(&f, &ok[..1], &ok),
        Err(SolveError::Length {
            what: "rho",
            len: 1,
            n: 2
        })
    );
    assert!(matches!(
        solve_bounces(&f, &ok, &ok[..1], 3),
        Err(SolveError::Length { what: "e", .. })
    ));
    assert!(matches!(
        residual(&f, &ok, &ok, &ok[..1]),
        Err(SolveError::Length { what: "b", .. })
    ));
    for value in [1.5, -0.1, f64::NAN, f64::INFINITY] {
        let mut rho = ok;
        rho[1][2] = value;
        assert!(matches!(
            solve_direct(&f, &rho, &ok),
            Err(SolveError::Reflectance {
                element: 1,
                band: 2,
                ..
            })
        ));
    }
    let mut e = ok;
    e[0][1] = f64::INFINITY;
    assert!(matches!(
        solve_bounces(&f, &ok, &e, 1),
        Err(SolveError::Emission {
            element: 0,
            band: 1,
            ..
        })
    ));
}

/// An operator that implements only `apply`, as a matrix-free one might.
struct OnlyApply<'a>(DenseMatrix<'a>);

impl Operator for OnlyApply<'_> {
    fn n(&self) -> usize {
        self.0.n()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.0.apply(x, y)
    }
}

#[test]
fn any_operator_plugs_into_the_bounce_solver() {
    let n = 150;
    let f = closed_form_factors(n, 12);
    let dense = DenseMatrix::new(n, &f).unwrap();
    let (rho, e) = coloured_scene(n, 13);
    let a = solve_bounces(&dense, &rho, &e, 7).unwrap();
    // The default `apply_bands` (three `apply` calls) gives the fused pass's bits.
    let op: &dyn Operator = &OnlyApply(dense);
    let b = solve_bounces(op, &rho, &e, 7).unwrap();
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.residual, b.residual);
}

/// An operator that amplifies light a lot.
struct Amplifier(usize);

impl Operator for Amplifier {
    fn n(&self) -> usize {
        self.0
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let sum: f64 = x.iter().sum();
        y.iter_mut().for_each(|y| *y = 1e200 * sum);
    }
}

#[test]
fn divergent_bounces_are_errors() {
    let rho = [[1.0; 3]; 3];
    let e = [[1.0; 3]; 3];
    assert_eq!(
        solve_bounces(&Amplifier(3), &rho, &e, 10),
        Err(SolveError::Diverged {
            band: 0,
            bounces: 1
        })
    );
}

#[test]
fn results_do_not_depend_on_thread_count() {
    // Large enough for faer's parallel LU (it goes sequential below 128 × 128).
    let n = 700;
    let f = closed_form_factors(n, 14);
    let f = DenseMatrix::new(n, &f).unwrap();
    let (rho, e) = coloured_scene(n, 15);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            (
                solve_direct(&f, &rho, &e).unwrap(),
                solve_bounces(&f, &rho, &e, 20).unwrap(),
            )
        })
    };
    let (direct1, bounces1) = run(1);
    assert!(direct1.residual.iter().all(|&r| r < 1e-12));
    for threads in [2, 3, 4] {
        let (direct, bounces) = run(threads);
        assert!(bits(&direct) == bits(&direct1), "direct, {threads} threads");
        assert!(
            bits(&bounces) == bits(&bounces1),
            "bounces, {threads} threads"
        );
    }
}
