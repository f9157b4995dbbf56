//! The sound of a shape: a solid cut into voxels (bricks that span its bounding box
//! exactly, cubes when its sides allow), each an 8-node trilinear hexahedron of an
//! isotropic material, assembled into the stiffness K and the consistent mass M of
//! the whole; the modes are the solutions of K·φ = ω²·M·φ.
//!
//! - **Elements** ([`hex8`]): exact 2×2×2 Gauss integration of BᵀDB and ρ·NᵀN over a
//!   brick of sides hx × hy × hz, with Wilson's nine incompatible modes condensed out
//!   of the stiffness so that it does not lock in bending. It represents every linear
//!   displacement field exactly (uniform strain, rigid motion), so the patch test
//!   holds to rounding.
//! - **Grids** ([`grid`]): the voxels a solid fills, the nodes they share numbered in
//!   order (x fastest), K and M assembled as sparse symmetric matrices (3 degrees of
//!   freedom per node, x, y, z).
//! - **Shapes** ([`shape`]): boxes, spheres, cylinders, tubes and triangle meshes (OBJ)
//!   turned into voxels, with a voxel size that puts 2 through the thinnest wall within a
//!   budget of degrees of freedom; broken meshes (holes, non-manifold edges,
//!   self-intersections) are voxelised by a vote of rays along three axes, with warnings.
//! - **Ordering** ([`order`]): the grid's nodes in nested-dissection order, cut by
//!   lattice planes, so the Cholesky factor of K − σM fills less than under minimum
//!   degree on solids that are thick in two or three directions.
//!
//! Units are SI: metres, pascals, kilograms per cubic metre; ω in rad/s.

pub mod cache;
pub mod grid;
pub mod hex8;
pub mod model;
pub mod order;
pub mod shape;
pub mod solve;

/// An isotropic, linear elastic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Elastic {
    /// Young's modulus E, Pa.
    pub youngs: f64,
    /// Poisson's ratio ν, in (−1, 0.5).
    pub poisson: f64,
    /// Density ρ, kg/m³.
    pub density: f64,
}

impl Elastic {
    /// Lamé's first parameter λ = E·ν/((1 + ν)(1 − 2ν)), Pa.
    pub fn lambda(&self) -> f64 {
        let (e, nu) = (self.youngs, self.poisson);
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// The shear modulus μ = E/(2(1 + ν)), Pa.
    pub fn shear(&self) -> f64 {
        self.youngs / (2.0 * (1.0 + self.poisson))
    }
}
