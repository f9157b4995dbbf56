//! A fill-reducing order of a voxel grid's nodes for the Cholesky factor of K − σM:
//! geometric nested dissection (George, "Nested dissection of a regular finite element
//! mesh", SIAM J. Numer. Anal. 10(2), 1973).
//!
//! A hexahedron couples only nodes one lattice step apart along each axis, so the
//! plane of lattice nodes at one coordinate separates the nodes on either side: no
//! entry of K couples them. Ordering the two sides first and the plane last confines
//! the fill of each side to itself; the plane's nodes alone become a dense block.
//! Applied recursively, each part cut across its longest extent, a cube of n nodes
//! factors in O(n²) operations with O(n^{4/3}) entries, against the far heavier fill
//! that minimum degree leaves on a 3D lattice.
//!
//! Nodes are placed on the lattice by the rank of each coordinate among the distinct
//! values along its axis, so no voxel size is needed and no rounding decides: two
//! nodes of one voxel have ranks at most one apart, which is all a separator needs.
//! Parts of at most [`LEAF_NODES`] nodes keep the order they came in (the grid's,
//! x fastest). Everything is integer work in a fixed order: the same nodes give the
//! same order.

/// Parts of at most this many nodes are not cut further.
pub const LEAF_NODES: usize = 64;

/// The nodes in the order to eliminate them: `order[k]` is the node eliminated k-th.
pub fn nested_dissection(nodes: &[[f64; 3]]) -> Vec<usize> {
    let lattice = lattice_coordinates(nodes);
    let mut order = Vec::with_capacity(nodes.len());
    dissect(&lattice, (0..nodes.len()).collect(), &mut order);
    order
}

/// The degrees of freedom (three per node, x, y, z, kept together) in the order of
/// [`nested_dissection`]: `order[k]` is the degree of freedom eliminated k-th.
pub fn nested_dissection_dofs(nodes: &[[f64; 3]]) -> Vec<usize> {
    nested_dissection(nodes)
        .into_iter()
        .flat_map(|node| [3 * node, 3 * node + 1, 3 * node + 2])
        .collect()
}

/// Each node's coordinates as ranks among the distinct values along each axis.
fn lattice_coordinates(nodes: &[[f64; 3]]) -> Vec<[usize; 3]> {
    let mut lattice = vec![[0usize; 3]; nodes.len()];
    for axis in 0..3 {
        let mut values: Vec<f64> = nodes.iter().map(|p| p[axis]).collect();
        values.sort_by(f64::total_cmp);
        values.dedup_by(|a, b| a.total_cmp(b).is_eq());
        for (node, p) in nodes.iter().enumerate() {
            // Every node's value is among `values`, so the search finds it.
            lattice[node][axis] = values
                .binary_search_by(|v| v.total_cmp(&p[axis]))
                .unwrap_or_else(|at| at);
        }
    }
    lattice
}

/// Appends the nodes of `part` to `order`: the part below the middle plane of its
/// longest extent, the part above it, then the plane.
fn dissect(lattice: &[[usize; 3]], part: Vec<usize>, order: &mut Vec<usize>) {
    if part.len() <= LEAF_NODES {
        order.extend(part);
        return;
    }
    let mut low = [usize::MAX; 3];
    let mut high = [0usize; 3];
    for &node in &part {
        for axis in 0..3 {
            low[axis] = low[axis].min(lattice[node][axis]);
            high[axis] = high[axis].max(lattice[node][axis]);
        }
    }
    let extent = |axis: usize| high[axis] - low[axis];
    let axis = (0..3).fold(0, |best, a| if extent(a) > extent(best) { a } else { best });
    // Fewer than three planes leave no plane with nodes on both sides.
    if extent(axis) < 2 {
        order.extend(part);
        return;
    }
    let middle = low[axis] + extent(axis) / 2;
    let (mut below, mut above, mut plane) = (Vec::new(), Vec::new(), Vec::new());
    for node in part {
        match lattice[node][axis].cmp(&middle) {
            std::cmp::Ordering::Less => below.push(node),
            std::cmp::Ordering::Greater => above.push(node),
            std::cmp::Ordering::Equal => plane.push(node),
        }
    }
    dissect(lattice, below, order);
    dissect(lattice, above, order);
    order.extend(plane);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(n: usize, h: f64) -> Vec<[f64; 3]> {
        let mut nodes = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    nodes.push([i as f64 * h, j as f64 * h, k as f64 * h]);
                }
            }
        }
        nodes
    }

    #[test]
    fn the_order_is_a_permutation_ending_with_the_middle_plane() {
        let nodes = cube(9, 0.01);
        let order = nested_dissection(&nodes);
        let mut seen = order.clone();
        seen.sort();
        assert_eq!(seen, (0..nodes.len()).collect::<Vec<_>>());
        // The first cut is across x (the first of equal extents) at the fifth plane:
        // its 81 nodes come last, in grid order.
        let last: Vec<usize> = order[order.len() - 81..].to_vec();
        let plane: Vec<usize> = (0..nodes.len()).filter(|n| n % 9 == 4).collect();
        assert_eq!(last, plane);
    }

    #[test]
    fn no_node_before_a_plane_touches_a_node_after_it_on_the_other_side() {
        // Within the order, the part below the first plane comes first and shares no
        // voxel with the part above.
        let nodes = cube(9, 0.01);
        let order = nested_dissection(&nodes);
        let lattice = lattice_coordinates(&nodes);
        let below = &order[..(order.len() - 81) / 2];
        assert!(below.iter().all(|&n| lattice[n][0] < 4));
    }

    /// The symbolic Cholesky factor's size for a grid's K in an ordering.
    fn factor_size(dims: [usize; 3], ordering: Option<&[usize]>) -> usize {
        use faer::perm::PermRef;
        use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, SymmetricOrdering};
        use faer::sparse::SymbolicSparseColMat;
        use faer::Side;
        let material = crate::Elastic {
            youngs: 1.0,
            poisson: 0.3,
            density: 1.0,
        };
        let solid = crate::grid::VoxelGrid::solid(dims, 1.0).assemble(&material);
        let k = &solid.stiffness;
        // The lower triangle of K, column by column (its rows, K being symmetric).
        let mut starts = vec![0];
        let mut rows = Vec::new();
        for r in 0..k.size {
            rows.extend(
                k.columns[k.rows[r]..k.rows[r + 1]]
                    .iter()
                    .filter(|&&c| c >= r),
            );
            starts.push(rows.len());
        }
        let pattern = SymbolicSparseColMat::new_checked(k.size, k.size, starts, None, rows);
        let inverse: Vec<usize> = ordering.map_or(Vec::new(), |forward| {
            let mut inverse = vec![0; forward.len()];
            forward
                .iter()
                .enumerate()
                .for_each(|(new, &old)| inverse[old] = new);
            inverse
        });
        let ordering = match ordering {
            Some(forward) => {
                SymmetricOrdering::Custom(PermRef::new_checked(forward, &inverse, k.size))
            }
            None => SymmetricOrdering::Amd,
        };
        factorize_symbolic_cholesky(pattern.as_ref(), Side::Lower, ordering, Default::default())
            .map(|s| s.len_val())
            .unwrap_or(usize::MAX)
    }

    #[test]
    fn dissection_fills_a_cube_less_than_minimum_degree_and_grid_order() {
        let dims = [12, 12, 12];
        let nodes: Vec<[f64; 3]> = {
            let mut nodes = Vec::new();
            for k in 0..=12 {
                for j in 0..=12 {
                    for i in 0..=12 {
                        nodes.push([i as f64, j as f64, k as f64]);
                    }
                }
            }
            nodes
        };
        let dissection = factor_size(dims, Some(&nested_dissection_dofs(&nodes)));
        let minimum_degree = factor_size(dims, None);
        let grid_order: Vec<usize> = (0..3 * nodes.len()).collect();
        let banded = factor_size(dims, Some(&grid_order));
        assert!(
            dissection < minimum_degree && dissection < banded,
            "entries of L: dissection {dissection}, minimum degree {minimum_degree}, \
             grid order {banded}"
        );
    }

    #[test]
    fn ranks_ignore_the_voxel_size_and_gaps() {
        let nodes = [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.9, 0.1, 0.0]];
        assert_eq!(
            lattice_coordinates(&nodes),
            vec![[0, 0, 0], [1, 0, 0], [2, 1, 0]]
        );
    }
}
