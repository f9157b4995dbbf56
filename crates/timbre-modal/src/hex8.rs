//! The 8-node trilinear hexahedron on a brick (a rectangular voxel) of sides
//! hx × hy × hz: its stiffness and consistent mass, 24 × 24 (node k's x, y, z at 3k,
//! 3k + 1, 3k + 2).
//!
//! Node k sits at the corner ((k & 1)·hx, (k >> 1 & 1)·hy, (k >> 2 & 1)·hz); its shape
//! function in the brick's natural coordinates ξ, η, ζ ∈ [−1, 1] is
//! N_k = (1 + ξ·ξ_k)(1 + η·η_k)(1 + ζ·ζ_k)/8. The Jacobian is diag(hx, hy, hz)/2, so
//! ∂N/∂x_a = (2/h_a)·∂N/∂ξ_a and dV = (hx·hy·hz/8)·dξ·dη·dζ. Strains in Voigt order
//! (εxx, εyy, εzz, γxy, γyz, γzx); D = λ·m·mᵀ + μ·diag(2, 2, 2, 1, 1, 1) with
//! m = (1, 1, 1, 0, 0, 0).
//!
//! K = Σ_g Bᵀ·D·B·hx·hy·hz/8 and M = ρ·Σ_g Nᵀ·N·hx·hy·hz/8 over the 2 × 2 × 2 Gauss
//! points ±1/√3 (weights 1): exact for both, as their integrands are of degree at most
//! 2 in each coordinate.
//!
//! **Incompatible modes.** A trilinear element bent has shear strain it should not
//! (it cannot curve), so it is too stiff in bending ("locks"): 4 across a beam's
//! thickness are needed for its modes within 2 %. Nine internal displacements are
//! added, (1 − ξ²), (1 − η²), (1 − ζ²) for each component (E. L. Wilson, R. L. Taylor,
//! W. P. Doherty and J. Ghaboussi, "Incompatible displacement models", in Numerical
//! and Computer Methods in Structural Mechanics, 1973), which let the element curve,
//! and condensed out of its stiffness: K = K_uu − K_ub·K_bb⁻¹·K_bu. On a brick (a
//! constant Jacobian) the element still passes the patch test, and a free beam one
//! voxel thick bends within 0.4 % of Euler–Bernoulli (tests/beam.rs). The mass is
//! the trilinear one: the internal displacements carry none.

// Index loops write the sums of the formulas as they are printed.
#![allow(clippy::needless_range_loop)]

use crate::Elastic;

/// Degrees of freedom of one element.
pub const DOFS: usize = 24;

/// The corner of node `k` in natural coordinates (each −1 or 1).
fn corner(k: usize) -> [f64; 3] {
    [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(|b| if b == 0 { -1.0 } else { 1.0 })
}

/// The Gauss points of the 2 × 2 × 2 rule.
fn gauss_points() -> impl Iterator<Item = [f64; 3]> {
    let g = 1.0 / 3f64.sqrt();
    (0..8).map(move |k| corner(k).map(|c| c * g))
}

/// The shape functions and their natural derivatives at a point.
fn shape(p: [f64; 3]) -> ([f64; 8], [[f64; 3]; 8]) {
    let mut n = [0.0; 8];
    let mut dn = [[0.0; 3]; 8];
    for k in 0..8 {
        let c = corner(k);
        let f = [0, 1, 2].map(|i| 1.0 + p[i] * c[i]);
        n[k] = f[0] * f[1] * f[2] / 8.0;
        dn[k] = [
            c[0] * f[1] * f[2] / 8.0,
            f[0] * c[1] * f[2] / 8.0,
            f[0] * f[1] * c[2] / 8.0,
        ];
    }
    (n, dn)
}

/// Internal displacements of the incompatible modes: (1 − ξ_a²) along each axis a,
/// for each component.
const BUBBLES: usize = 9;

/// The element's stiffness for a brick of `sides` (hx, hy, hz), its incompatible
/// modes condensed out (see the module docs).
pub fn stiffness(material: &Elastic, sides: [f64; 3]) -> [[f64; DOFS]; DOFS] {
    let d = elasticity(material);
    let mut k = [[0.0; DOFS]; DOFS];
    // K_ab (24 × 9) and K_bb (9 × 9) by the same Gauss rule (exact: the bubbles'
    // strains are linear in ξ).
    let mut kab = [[0.0; BUBBLES]; DOFS];
    let mut kbb = [[0.0; BUBBLES]; BUBBLES];
    for p in gauss_points() {
        let (b, bubble) = (trilinear_strain(p, sides), bubble_strain(p, sides));
        add_weak_form(&mut k, &b, &d, &b, sides);
        add_weak_form(&mut kab, &b, &d, &bubble, sides);
        add_weak_form(&mut kbb, &bubble, &d, &bubble, sides);
    }
    // K − K_ab·K_bb⁻¹·K_ba, K_bb⁻¹ by Gauss–Jordan on the 9 × 9 (symmetric positive
    // definite: each bubble strains the voxel).
    let inverse = invert(kbb);
    for i in 0..DOFS {
        let row: [f64; BUBBLES] =
            std::array::from_fn(|a| (0..BUBBLES).map(|c| kab[i][c] * inverse[c][a]).sum());
        for j in 0..DOFS {
            k[i][j] -= (0..BUBBLES).map(|a| row[a] * kab[j][a]).sum::<f64>();
        }
    }
    // Exactly symmetric.
    for i in 0..DOFS {
        for j in 0..i {
            let mean = 0.5 * (k[i][j] + k[j][i]);
            k[i][j] = mean;
            k[j][i] = mean;
        }
    }
    k
}

/// D = λ·m·mᵀ + μ·diag(2, 2, 2, 1, 1, 1).
fn elasticity(material: &Elastic) -> [[f64; 6]; 6] {
    let (lambda, mu) = (material.lambda(), material.shear());
    let mut d = [[0.0; 6]; 6];
    for i in 0..3 {
        for j in 0..3 {
            d[i][j] = lambda;
        }
        d[i][i] += 2.0 * mu;
        d[i + 3][i + 3] = mu;
    }
    d
}

/// The strains of the nine bubbles at `p` (6 × 9): bubble 3a + i displaces
/// component i by (1 − ξ_a²), whose only derivative is ∂/∂x_a = −2ξ_a·(2/h_a).
fn bubble_strain(p: [f64; 3], sides: [f64; 3]) -> [[f64; BUBBLES]; 6] {
    let mut b = [[0.0; BUBBLES]; 6];
    for a in 0..3 {
        let g = -2.0 * p[a] * 2.0 / sides[a];
        for i in 0..3 {
            let row = match (i.min(a), i.max(a)) {
                (x, y) if x == y => x,
                (0, 1) => 3,
                (1, 2) => 4,
                _ => 5,
            };
            b[row][3 * a + i] = g;
        }
    }
    b
}

/// The inverse of a symmetric positive definite 9 × 9, by Gauss–Jordan.
fn invert(mut a: [[f64; BUBBLES]; BUBBLES]) -> [[f64; BUBBLES]; BUBBLES] {
    let mut inverse = [[0.0; BUBBLES]; BUBBLES];
    for i in 0..BUBBLES {
        inverse[i][i] = 1.0;
    }
    for c in 0..BUBBLES {
        let pivot = a[c][c];
        for j in 0..BUBBLES {
            a[c][j] /= pivot;
            inverse[c][j] /= pivot;
        }
        for r in 0..BUBBLES {
            if r != c {
                let f = a[r][c];
                for j in 0..BUBBLES {
                    a[r][j] -= f * a[c][j];
                    inverse[r][j] -= f * inverse[c][j];
                }
            }
        }
    }
    inverse
}

/// B of the trilinear field at `p` (6 × 24).
fn trilinear_strain(p: [f64; 3], sides: [f64; 3]) -> [[f64; DOFS]; 6] {
    let (_, dn) = shape(p);
    let mut b = [[0.0; DOFS]; 6];
    for node in 0..8 {
        let [dx, dy, dz] = [0, 1, 2].map(|a| dn[node][a] * 2.0 / sides[a]);
        let c = 3 * node;
        b[0][c] = dx;
        b[1][c + 1] = dy;
        b[2][c + 2] = dz;
        b[3][c] = dy;
        b[3][c + 1] = dx;
        b[4][c + 1] = dz;
        b[4][c + 2] = dy;
        b[5][c] = dz;
        b[5][c + 2] = dx;
    }
    b
}

/// out += Lᵀ·D·R·hx·hy·hz/8: one Gauss point's share of a stiffness block, between the
/// strains L of one set of displacements and R of another.
fn add_weak_form<const A: usize, const B: usize>(
    out: &mut [[f64; B]; A],
    left: &[[f64; A]; 6],
    d: &[[f64; 6]; 6],
    right: &[[f64; B]; 6],
    sides: [f64; 3],
) {
    let volume = jacobian(sides);
    // D·R, then Lᵀ·(D·R).
    let mut dr = [[0.0; B]; 6];
    for i in 0..6 {
        for j in 0..B {
            dr[i][j] = (0..6).map(|m| d[i][m] * right[m][j]).sum();
        }
    }
    for i in 0..A {
        for j in 0..B {
            out[i][j] += volume * (0..6).map(|m| left[m][i] * dr[m][j]).sum::<f64>();
        }
    }
}

/// The Jacobian determinant hx·hy·hz/8 of a brick of `sides`: each Gauss point's
/// weight in volume (on a cube, (h/2)³ to the bit: halving is exact).
fn jacobian(sides: [f64; 3]) -> f64 {
    sides[0] * sides[1] * sides[2] / 8.0
}

/// The element's consistent mass for a brick of `sides` (hx, hy, hz).
pub fn mass(material: &Elastic, sides: [f64; 3]) -> [[f64; DOFS]; DOFS] {
    let volume = jacobian(sides);
    let mut m = [[0.0; DOFS]; DOFS];
    for p in gauss_points() {
        let (n, _) = shape(p);
        for a in 0..8 {
            for b in 0..8 {
                let value = material.density * n[a] * n[b] * volume;
                for i in 0..3 {
                    m[3 * a + i][3 * b + i] += value;
                }
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    const STEEL: Elastic = Elastic {
        youngs: 200e9,
        poisson: 0.3,
        density: 7850.0,
    };

    /// A brick of three different sides, m.
    const BRICK: [f64; 3] = [0.01, 0.0073, 0.0129];

    /// The displacement of every node of a brick of `sides` under the field `u`.
    fn nodal(sides: [f64; 3], u: impl Fn([f64; 3]) -> [f64; 3]) -> [f64; DOFS] {
        let mut out = [0.0; DOFS];
        for k in 0..8 {
            let c = corner(k);
            let x = [0, 1, 2].map(|a| (c[a] + 1.0) / 2.0 * sides[a]);
            out[3 * k..3 * k + 3].copy_from_slice(&u(x));
        }
        out
    }

    /// uᵀ·A·u.
    fn quadratic(a: &[[f64; DOFS]; DOFS], u: &[f64; DOFS]) -> f64 {
        (0..DOFS)
            .map(|i| u[i] * (0..DOFS).map(|j| a[i][j] * u[j]).sum::<f64>())
            .sum::<f64>()
    }

    #[test]
    fn rigid_motions_store_no_energy_in_a_brick() {
        let k = stiffness(&STEEL, BRICK);
        let rigid: [fn([f64; 3]) -> [f64; 3]; 6] = [
            |_| [1.0, 0.0, 0.0],
            |_| [0.0, 1.0, 0.0],
            |_| [0.0, 0.0, 1.0],
            |[_, y, z]| [0.0, -z, y],
            |[x, _, z]| [z, 0.0, -x],
            |[x, y, _]| [-y, x, 0.0],
        ];
        for u in rigid {
            let u = nodal(BRICK, u);
            let size = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(quadratic(&k, &u).abs() < 1e-12 * k[0][0] * size * size);
        }
        let scale = k[0][0];
        for i in 0..DOFS {
            for j in 0..DOFS {
                assert!((k[i][j] - k[j][i]).abs() <= 1e-12 * scale);
            }
        }
    }

    /// The patch test on a brick of unequal sides: a displacement gradient G (any
    /// linear field) stores ½·εᵀ·D·ε·hx·hy·hz, ε the symmetric part of G in Voigt
    /// order, to 1e-12 relative.
    #[test]
    fn every_uniform_strain_of_a_brick_stores_the_exact_energy() {
        let k = stiffness(&STEEL, BRICK);
        let d = elasticity(&STEEL);
        let volume = BRICK[0] * BRICK[1] * BRICK[2];
        let e = 1e-4;
        let mut gradients: Vec<[[f64; 3]; 3]> = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                let mut g = [[0.0; 3]; 3];
                g[i][j] = e;
                gradients.push(g);
            }
        }
        gradients.push([
            [e, -0.3 * e, 0.7 * e],
            [0.2 * e, -e, 0.4 * e],
            [0.9 * e, 0.1 * e, 0.5 * e],
        ]);
        for g in gradients {
            let u = nodal(BRICK, |x| {
                [0, 1, 2].map(|i| (0..3).map(|j| g[i][j] * x[j]).sum::<f64>())
            });
            let strain = [
                g[0][0],
                g[1][1],
                g[2][2],
                g[0][1] + g[1][0],
                g[1][2] + g[2][1],
                g[2][0] + g[0][2],
            ];
            let expected: f64 = 0.5
                * volume
                * (0..6)
                    .map(|i| strain[i] * (0..6).map(|j| d[i][j] * strain[j]).sum::<f64>())
                    .sum::<f64>();
            let found = 0.5 * quadratic(&k, &u);
            assert!(
                (found / expected - 1.0).abs() < 1e-12,
                "{g:?}: {found} {expected}"
            );
        }
    }

    #[test]
    fn the_mass_is_the_brick_s_along_each_axis_and_its_inertia_is_exact() {
        let [hx, hy, hz] = BRICK;
        let m = mass(&STEEL, BRICK);
        let total = STEEL.density * hx * hy * hz;
        for axis in 0..3 {
            let u = nodal(BRICK, |_| {
                let mut v = [0.0; 3];
                v[axis] = 1.0;
                v
            });
            assert!((quadratic(&m, &u) / total - 1.0).abs() < 1e-12);
        }
        // A rotation about the brick's x edge:
        // ∫ρ(y² + z²)dV = ρ·hx·hy·hz·(hy² + hz²)/3.
        let u = nodal(BRICK, |[_, y, z]| [0.0, -z, y]);
        let expected = total * (hy * hy + hz * hz) / 3.0;
        assert!((quadratic(&m, &u) / expected - 1.0).abs() < 1e-12);
    }

    /// A brick of equal sides is the cube element that came before bricks, bit for
    /// bit: the fingerprints of its 576 stiffness and 576 mass entries, recorded from
    /// that element (steel, h = 10 mm).
    #[test]
    fn a_brick_of_equal_sides_is_the_cube_element_bit_for_bit() {
        let fingerprint = |a: &[[f64; DOFS]; DOFS]| {
            a.iter().flatten().enumerate().fold(0u64, |h, (i, v)| {
                h.rotate_left(7) ^ v.to_bits().wrapping_mul(i as u64 * 2 + 1)
            })
        };
        let k = stiffness(&STEEL, [0.01; 3]);
        let m = mass(&STEEL, [0.01; 3]);
        assert_eq!(k[0][0], 4.1742979242979246e8);
        assert_eq!(k[5][17], -1.6101953601953605e8);
        assert_eq!(fingerprint(&k), 0x79272cb4b90b55e4);
        assert_eq!(fingerprint(&m), 0x26c673fd8972d3fc);
    }
}
