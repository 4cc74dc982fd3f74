//! The light-transport operator of a scene: what the solver multiplies by.
//!
//! A [`Transport`] holds `F` (the fraction of the light leaving element i that reaches element
//! j, Goral et al. 1984, eq. 7) in whatever form it was built, and offers the two products a
//! bake needs: `y = F x` for the solver (through [`solver::Operator`]) and the irradiance
//! `H = F b` for lightmaps and the energy balance. Two implementations:
//!
//! - [`solver::DenseMatrix`]: every element pair's form factor, exact (the dense path);
//! - [`HierarchicalTransport`]: hierarchical radiosity (Hanrahan, Salzman & Aupperle 1991):
//!   each polygon is the root of a tree whose leaves are its elements, and light moves along
//!   links between the coarsest node pairs whose estimated error is small enough, with
//!   push–pull through the trees. O(n) links for a fixed error instead of n² pairs.
//!
//! [`build`] makes either from one [`Problem`] and its [`Options`]; the caller then asks the
//! [`BuiltOperator`] what it can do rather than matching on the kind.
//!
//! This crate is not the solver (that is pure linear algebra in `solver`) and does not choose
//! between the implementations (the `bake` library does); it knows elements only through the
//! mesher's grids, and form factors and visibility only through their crates' APIs.

mod build;
mod clusters;
pub mod hierarchical;

pub use build::{
    build, hierarchical, Built, BuiltOperator, DenseOptions, Options, Problem, Progress, Stats,
    View,
};
pub use hierarchical::{
    HierarchicalOptions, HierarchicalStats, HierarchicalTransport, LinkError, LinkMisses,
    LinkProgress, LinkTolerance, LinksFileError, MAX_AMPLIFICATION,
};
use solver::{Operator, BANDS};

/// A scene's light-transport operator.
pub trait Transport: Operator {
    /// `H_i = Σ_j F_ij b_j` per band: the light arriving at each element (its irradiance in
    /// the radiosity unit; ρ = 0 elements receive light too).
    fn irradiance(&self, b: &[[f64; BANDS]]) -> Vec<[f64; BANDS]> {
        let mut h = vec![[0.0; BANDS]; self.n()];
        self.apply_bands(b, &mut h);
        h
    }
}

/// The dense matrix: every pair exact.
impl Transport for solver::DenseMatrix<'_> {}
