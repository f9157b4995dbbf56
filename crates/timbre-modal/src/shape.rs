//! A shape turned into voxels for the finite elements of [`crate::grid`].
//!
//! - **Bricks**: the grid spans the shape's bounding box exactly. Along each axis a of
//!   length L_a it has n_a = max(1, round(L_a/h)) voxels of side h_a = L_a/n_a, h the
//!   voxel size asked for (or chosen), so a voxel is a brick whose sides differ from h
//!   by at most a quarter along an axis of 2 voxels or more. A box is filled
//!   exactly at any voxel size (its volume and mass are exact); a sphere's bricks are
//!   cubes; a mesh's volume is off only by the staircase of its boundary, not by up to
//!   half a voxel per side.
//! - **Primitives** (box, sphere, solid cylinder, tube): a voxel is filled when its
//!   centre is inside the shape. The grid is centred on the shape's centre, so a
//!   sphere, cylinder or tube is symmetric under the reflections of its axes (voxel
//!   centres are computed as (2i + 1 − n_a)·h_a/2, exactly opposite on either side).
//! - **Meshes**: inside and outside by rays along scanlines through the voxel centres,
//!   cast along x, y and z (Nooruddin & Turk, "Simplification and repair of polygonal
//!   models using volumetric techniques", IEEE TVCG 9(2), 2003). Along each scanline the
//!   crossings with the triangles are sorted; a line that crosses an odd number of
//!   times went through a hole or a broken part and abstains. On a line with an even
//!   count, a voxel is inside where the winding number (the crossings counted +1 or −1
//!   as the triangle faces along the ray or against it) is not zero, so parts that
//!   overlap or intersect each other make their union; where the line's windings do not
//!   cancel (faces flipped), the parity of the crossings decides instead. Each voxel is
//!   filled when a strict majority of the axes that did not abstain say inside (a tie
//!   or no vote: empty). A hole is thus closed over by the two axes that do not pass
//!   through it, and non-manifold edges and self-intersections need no repair. Open and
//!   non-manifold edges (used by one triangle or by more than two, after welding
//!   vertices at the same position) are reported as warnings, as are voxels on which
//!   the axes disagreed.
//! - **Rays through edges and vertices** are nudged deterministically: a scanline
//!   point on a triangle's edge is treated as moved by (ε, ε²) in the plane across the
//!   ray, for a vanishing ε (simulation of simplicity), and the edge function of an edge
//!   is computed from its endpoints in a fixed order, so the two triangles that share
//!   an edge get exactly opposite values and a ray through the edge crosses exactly one
//!   of them. Triangles edge-on to the ray are skipped (their neighbours' shared edges
//!   decide consistently).
//! - **Speed**: each triangle visits only the scanlines its projected bounding box
//!   covers, so the cost is the number of triangles plus the crossings plus the voxels.
//! - **Thinnest wall**: exact for primitives (a box's smallest side, a tube's
//!   outer − inner radius, a sphere's diameter, a cylinder's min(2r, height)). For a
//!   mesh it is estimated by the shape diameter: from points spread evenly over the
//!   triangles (about 4096 in all, at least one per triangle) a ray goes inward,
//!   against the outward normal (outward as the mesh's signed volume says), to the first
//!   surface it hits (`parry3d`); the wall is the 5th area-weighted percentile of those
//!   lengths, misses left out, and at most the smallest side of the bounding box. A
//!   100 × 100 × 4 mm plate gives 4 mm: all the rays from its two large faces cross it.
//! - **Resolution**: the elements do not lock in bending (their incompatible modes,
//!   [`crate::hex8`]), but a wall needs 2 voxels through it to be joined face to face
//!   where it curves. The voxels across a wall are counted along each axis with the
//!   brick's side there: a primitive's thickness along each axis (a box's sides; a
//!   tube's wall across x and y, its length along z), and a mesh's thinnest wall
//!   along every axis (its walls have no one direction; the largest side never
//!   overcounts). Unless a voxel size is given, it is h = min(h_wall, longest side /
//!   32), h_wall the largest voxel size that puts 2 across every wall, enlarged just
//!   enough that the degrees of freedom (3 per node) fit [`Resolution::max_dofs`]. The
//!   count is estimated before any grid is allocated from the solid's volume V, the
//!   area S of the staircase its surface makes on a grid (Σ (|nx| + |ny| + |nz|)·area)
//!   and the length E of its staircase edges, with ĥ = ∛(hx·hy·hz):
//!   nodes ≈ V/(hx·hy·hz) + S/(2ĥ²) + E/(4ĥ) + 1 (for a box, exactly
//!   (nx + 1)(ny + 1)(nz + 1)), then checked on the filled grid. A given voxel size
//!   over the limit is refused; so is a bounding grid of more than 2²⁸ voxels. Fewer
//!   than 2 voxels through a wall is a warning that names h_wall and the degrees of
//!   freedom it would take.
//!
//! Everything is computed in one thread in a fixed order: the same input gives the
//! same grid, bit for bit.

mod mesh;
mod report;
mod scan;
mod wall;

pub use mesh::{Topology, TriangleMesh};
pub use report::{ShapeError, ShapeWarning};

use crate::grid::VoxelGrid;

/// The most voxels a bounding grid may hold (2²⁸), whatever the degrees of freedom.
pub const MAX_GRID_VOXELS: usize = 1 << 28;

/// Voxels through the thinnest wall below which bending modes are too stiff: with
/// fewer, a thin curved wall is voxels that touch only at their edges (hinges). The
/// element itself does not lock: a beam one voxel thick bends within 0.4 % of
/// Euler–Bernoulli (tests/beam.rs).
pub const WALL_VOXELS: f64 = 2.0;

/// Voxels along the longest side when the thinnest wall asks for fewer.
pub const LONGEST_SIDE_VOXELS: f64 = 32.0;

/// A solid to analyse, in metres, in its own coordinates.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A box of sides (x, y, z), centred on the origin (plates and bars are boxes).
    Box { size: [f64; 3] },
    /// A ball centred on the origin.
    Sphere { radius: f64 },
    /// A solid cylinder along z, centred on the origin.
    Cylinder { radius: f64, height: f64 },
    /// A hollow tube along z, centred on the origin (inner 0: a rod).
    Tube { outer: f64, inner: f64, length: f64 },
    /// A triangle mesh, in the coordinates of its file.
    Mesh(TriangleMesh),
}

/// How fine the grid is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolution {
    /// The voxel size h asked for, m: each axis of length L gets round(L/h) voxels
    /// (at least 1), bricks of side L/round(L/h); None: chosen (see the module docs).
    pub voxel: Option<f64>,
    /// The most degrees of freedom (3 per node) allowed; more is refused before the
    /// grid is allocated.
    pub max_dofs: usize,
}

impl Default for Resolution {
    /// A chosen voxel size and at most 150 000 degrees of freedom.
    fn default() -> Self {
        Resolution {
            voxel: None,
            max_dofs: 150_000,
        }
    }
}

/// A shape as filled voxels, with what was noticed on the way.
#[derive(Clone, Debug, PartialEq)]
pub struct Voxelized {
    /// The filled voxels.
    pub grid: VoxelGrid,
    /// Where the grid's corner (voxel (0, 0, 0)'s lowest corner) lies in the shape's
    /// coordinates, m.
    pub origin: [f64; 3],
    /// The thinnest wall of the shape, m (an estimate for meshes, exact for primitives).
    pub thinnest_wall: f64,
    /// How many voxels cross the walls: the least along an axis of the shape's
    /// thickness there over the brick's side (see the module docs).
    pub voxels_across_wall: f64,
    /// The degrees of freedom of the filled grid: 3 per node of a filled voxel.
    pub dofs: usize,
    /// What the caller should hear about, in the order found.
    pub warnings: Vec<ShapeWarning>,
}

/// The voxels of `shape` at `resolution`, or why not. See the module docs for how.
pub fn voxelize(shape: &Shape, resolution: &Resolution) -> Result<Voxelized, ShapeError> {
    let mut warnings = Vec::new();
    let solid = Solid::measure(shape, &mut warnings)?;
    let mut h = match resolution.voxel {
        Some(voxel) => {
            if !(voxel.is_finite() && voxel > 0.0) {
                return Err(ShapeError::BadVoxel { value: voxel });
            }
            solid.admit(voxel, resolution.max_dofs)?;
            voxel
        }
        None => solid.choose_voxel(resolution.max_dofs)?,
    };
    // The estimate may undercount (a curved staircase, an open mesh's volume): check
    // the filled grid, and when the size was chosen, enlarge it until it fits.
    let mut tries = 0;
    let (grid, origin, dofs, not_unanimous) = loop {
        let (grid, origin, not_unanimous) = solid.fill(h);
        let dofs = count_dofs(&grid);
        if dofs <= resolution.max_dofs {
            break (grid, origin, dofs, not_unanimous);
        }
        tries += 1;
        // Degrees of freedom go about as 1/h³.
        let larger = h * (dofs as f64 / resolution.max_dofs as f64).cbrt() * 1.02;
        if resolution.voxel.is_some() || tries > 8 {
            return Err(ShapeError::TooManyDofs {
                voxel: h,
                estimated: dofs,
                limit: resolution.max_dofs,
                fitting_voxel: (tries <= 8).then_some(larger),
            });
        }
        h = larger;
    };
    let filled = grid.filled.iter().filter(|&&f| f).count();
    if filled == 0 {
        return Err(ShapeError::NothingFilled {
            voxel: h,
            suggested: solid.voxel_for_wall(),
        });
    }
    if not_unanimous > 0 {
        warnings.push(ShapeWarning::RaysDisagreed {
            voxels: not_unanimous,
            filled,
        });
    }
    let (voxels_across, wall_across, side_across) = solid.voxels_across(h);
    if voxels_across < WALL_VOXELS * (1.0 - 1e-9) {
        let voxel_for_wall = solid.voxel_for_wall();
        warnings.push(ShapeWarning::TooThin {
            wall: wall_across,
            voxel: side_across,
            voxels_across,
            voxel_for_wall,
            dofs_for_wall: to_count(solid.estimate_dofs(voxel_for_wall)),
        });
    }
    Ok(Voxelized {
        grid,
        origin,
        thinnest_wall: solid.wall,
        voxels_across_wall: voxels_across,
        dofs,
        warnings,
    })
}

/// A shape checked and measured: what choosing a grid needs before allocating one.
struct Solid<'a> {
    shape: &'a Shape,
    /// The bounding box's sides and its lowest corner, m.
    extent: [f64; 3],
    low: [f64; 3],
    /// The thinnest wall, m: the least of `walls`.
    wall: f64,
    /// The thickness the voxels cross along each axis, m: a primitive's along that
    /// axis (a box's side; a tube's wall across x and y, its length along z); for a
    /// mesh, whose walls have no one direction, its thinnest wall along every axis.
    walls: [f64; 3],
    /// Volume V, staircase area S and staircase edge length E (see the module docs).
    volume: f64,
    staircase_area: f64,
    staircase_edges: f64,
}

impl<'a> Solid<'a> {
    fn measure(shape: &'a Shape, warnings: &mut Vec<ShapeWarning>) -> Result<Self, ShapeError> {
        use std::f64::consts::PI;
        let solid = |extent: [f64; 3], walls: [f64; 3], volume, area, edges| Solid {
            shape,
            extent,
            low: extent.map(|s| -0.5 * s),
            wall: walls.iter().cloned().fold(f64::INFINITY, f64::min),
            walls,
            volume,
            staircase_area: area,
            staircase_edges: edges,
        };
        Ok(match *shape {
            Shape::Box { size } => {
                for (value, name) in size.into_iter().zip(["x side", "y side", "z side"]) {
                    positive("box", name, value)?;
                }
                let [x, y, z] = size;
                solid(
                    size,
                    size,
                    x * y * z,
                    2.0 * (x * y + y * z + z * x),
                    4.0 * (x + y + z),
                )
            }
            Shape::Sphere { radius: r } => {
                positive("sphere", "radius", r)?;
                let d = 2.0 * r;
                solid(
                    [d; 3],
                    [d; 3],
                    4.0 / 3.0 * PI * r.powi(3),
                    6.0 * PI * r * r,
                    0.0,
                )
            }
            Shape::Cylinder { radius: r, height } => {
                positive("cylinder", "radius", r)?;
                positive("cylinder", "height", height)?;
                let d = 2.0 * r;
                let area = 8.0 * r * height + 2.0 * PI * r * r;
                solid(
                    [d, d, height],
                    [d, d, height],
                    PI * r * r * height,
                    area,
                    16.0 * r,
                )
            }
            Shape::Tube {
                outer,
                inner,
                length,
            } => {
                positive("tube", "outer radius", outer)?;
                positive("tube", "length", length)?;
                if !(inner.is_finite() && inner >= 0.0) {
                    return Err(ShapeError::BadDimension {
                        shape: "tube",
                        name: "inner radius",
                        value: inner,
                    });
                }
                if inner >= outer {
                    return Err(ShapeError::InnerNotBelowOuter { inner, outer });
                }
                let d = 2.0 * outer;
                let annulus = PI * (outer * outer - inner * inner);
                let area = 8.0 * (outer + inner) * length + 2.0 * annulus;
                let wall = if inner > 0.0 { outer - inner } else { d };
                solid(
                    [d, d, length],
                    [wall, wall, length],
                    annulus * length,
                    area,
                    16.0 * (outer + inner),
                )
            }
            Shape::Mesh(ref mesh) => Self::measure_mesh(shape, mesh, warnings)?,
        })
    }

    fn measure_mesh(
        shape: &'a Shape,
        mesh: &TriangleMesh,
        warnings: &mut Vec<ShapeWarning>,
    ) -> Result<Self, ShapeError> {
        mesh.check()?;
        let (low, high) = mesh.bounds();
        let extent = [0, 1, 2].map(|a| high[a] - low[a]);
        let longest = extent.iter().cloned().fold(0.0, f64::max);
        for (axis, &side) in extent.iter().enumerate() {
            if !side.is_finite() || side <= 1e-9 * longest {
                return Err(ShapeError::Flat { axis, extent: side });
            }
        }
        let topology = mesh.topology();
        if topology.open_edges > 0 {
            warnings.push(ShapeWarning::OpenMesh {
                edges: topology.open_edges,
            });
        }
        if topology.non_manifold_edges > 0 {
            warnings.push(ShapeWarning::NonManifold {
                edges: topology.non_manifold_edges,
            });
        }
        let smallest = extent.iter().cloned().fold(f64::INFINITY, f64::min);
        let wall = match wall::thinnest_wall(mesh) {
            Some(wall) => wall.min(smallest),
            None => {
                warnings.push(ShapeWarning::WallGuessed { wall: smallest });
                smallest
            }
        };
        let bounding_volume = extent[0] * extent[1] * extent[2];
        Ok(Solid {
            shape,
            extent,
            low,
            wall,
            walls: [wall; 3],
            volume: mesh.volume().abs().min(bounding_volume),
            staircase_area: mesh.projected_area(),
            staircase_edges: 4.0 * (extent[0] + extent[1] + extent[2]),
        })
    }

    /// The grid's size in voxels at voxel size `h`, as reals (may be huge): each side
    /// of the bounding box rounded to a whole number of voxels, at least 1.
    fn dims(&self, h: f64) -> [f64; 3] {
        self.extent.map(|s| (s / h).round().max(1.0))
    }

    /// The bricks' sides at voxel size `h`: each side of the bounding box over its
    /// voxels.
    fn sides(&self, h: f64) -> [f64; 3] {
        let dims = self.dims(h);
        [0, 1, 2].map(|a| self.extent[a] / dims[a])
    }

    /// The voxels across the walls at voxel size `h`: the least along an axis of
    /// its wall over its brick side, with that wall and side.
    fn voxels_across(&self, h: f64) -> (f64, f64, f64) {
        let sides = self.sides(h);
        (0..3)
            .map(|a| (self.walls[a] / sides[a], self.walls[a], sides[a]))
            .fold((f64::INFINITY, 0.0, 0.0), |least, x| {
                if x.0 < least.0 {
                    x
                } else {
                    least
                }
            })
    }

    /// The largest voxel size that puts [`WALL_VOXELS`] across every wall: the least
    /// of L_a/m_a, m_a = ⌈2·L_a/wall_a⌉ (at that size each axis gets at least m_a
    /// voxels, each at most half its wall).
    fn voxel_for_wall(&self) -> f64 {
        (0..3)
            .map(|a| {
                let length = self.extent[a];
                let most = self.walls[a] / WALL_VOXELS;
                length / (length / most - 1e-9).ceil().max(1.0)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// About how many degrees of freedom a grid of voxel size `h` takes (see the
    /// module docs).
    fn estimate_dofs(&self, h: f64) -> f64 {
        let nodes = match self.shape {
            Shape::Box { .. } => self.dims(h).iter().map(|n| n + 1.0).product(),
            _ => {
                let [hx, hy, hz] = self.sides(h);
                let mean = (hx * hy * hz).cbrt();
                self.volume / (hx * hy * hz)
                    + self.staircase_area / (2.0 * mean * mean)
                    + self.staircase_edges / (4.0 * mean)
                    + 1.0
            }
        };
        // At least one voxel's 8 nodes.
        3.0 * nodes.max(8.0)
    }

    fn grid_voxels(&self, h: f64) -> f64 {
        self.dims(h).iter().product()
    }

    fn fits(&self, h: f64, max_dofs: usize) -> bool {
        self.estimate_dofs(h) <= max_dofs as f64 && self.grid_voxels(h) <= MAX_GRID_VOXELS as f64
    }

    /// A given voxel size, or the refusal, decided before any grid is allocated.
    fn admit(&self, h: f64, max_dofs: usize) -> Result<(), ShapeError> {
        let estimated = self.estimate_dofs(h);
        if estimated > max_dofs as f64 {
            return Err(ShapeError::TooManyDofs {
                voxel: h,
                estimated: to_count(estimated),
                limit: max_dofs,
                fitting_voxel: self.smallest_fitting(h, max_dofs),
            });
        }
        let voxels = self.grid_voxels(h);
        if voxels > MAX_GRID_VOXELS as f64 {
            return Err(ShapeError::GridTooLarge {
                voxel: h,
                voxels,
                limit: MAX_GRID_VOXELS,
                fitting_voxel: self.smallest_fitting(h, max_dofs),
            });
        }
        Ok(())
    }

    /// h = min(h_wall, longest/32), enlarged until the grid fits.
    fn choose_voxel(&self, max_dofs: usize) -> Result<f64, ShapeError> {
        let longest = self.extent.iter().cloned().fold(0.0, f64::max);
        let first = self.voxel_for_wall().min(longest / LONGEST_SIDE_VOXELS);
        if self.fits(first, max_dofs) {
            return Ok(first);
        }
        self.smallest_fitting(first, max_dofs)
            .ok_or_else(|| ShapeError::TooManyDofs {
                voxel: first,
                estimated: to_count(self.estimate_dofs(first)),
                limit: max_dofs,
                fitting_voxel: None,
            })
    }

    /// The smallest voxel side above `h` (to a part in 10⁶) whose grid fits, found by
    /// doubling and bisection; None when even a grid of one voxel does not.
    fn smallest_fitting(&self, h: f64, max_dofs: usize) -> Option<f64> {
        let mut high = h;
        let mut doublings = 0;
        while !self.fits(high, max_dofs) {
            high *= 2.0;
            doublings += 1;
            if doublings > 200 || self.dims(high) == [1.0; 3] && !self.fits(high, max_dofs) {
                return None;
            }
        }
        let mut low = h;
        while high / low > 1.0 + 1e-6 {
            let middle = (low * high).sqrt();
            if self.fits(middle, max_dofs) {
                high = middle;
            } else {
                low = middle;
            }
        }
        Some(high)
    }

    /// The filled grid at voxel size `h`, its corner (the bounding box's lowest), and
    /// the voxels the axes did not agree on.
    fn fill(&self, h: f64) -> (VoxelGrid, [f64; 3], usize) {
        let dims = self.dims(h).map(|n| n as usize);
        let sides = self.sides(h);
        let origin = self.low;
        let centres =
            |inside: &dyn Fn(f64, f64, f64) -> bool| (fill_centres(dims, sides, inside), 0);
        let (filled, not_unanimous) = match *self.shape {
            Shape::Box { .. } => centres(&|_, _, _| true),
            Shape::Sphere { radius } => {
                centres(&|x, y, z| x * x + y * y + z * z <= radius * radius)
            }
            Shape::Cylinder { radius, height } => {
                centres(&|x, y, z| x * x + y * y <= radius * radius && 2.0 * z.abs() <= height)
            }
            Shape::Tube {
                outer,
                inner,
                length,
            } => centres(&|x, y, z| {
                let rho2 = x * x + y * y;
                inner * inner <= rho2 && rho2 <= outer * outer && 2.0 * z.abs() <= length
            }),
            Shape::Mesh(ref mesh) => {
                let placement = scan::Placement {
                    origin,
                    sides,
                    dims,
                };
                let scanned = scan::scan(mesh, &placement);
                (scanned.filled, scanned.not_unanimous)
            }
        };
        (
            VoxelGrid {
                dims,
                sides,
                filled,
            },
            origin,
            not_unanimous,
        )
    }
}

/// Whether each voxel's centre, relative to the grid's centre, is `inside`. The
/// centres are (2i + 1 − n_a)·h_a/2, exactly opposite on either side of the centre.
fn fill_centres(
    dims: [usize; 3],
    sides: [f64; 3],
    inside: &dyn Fn(f64, f64, f64) -> bool,
) -> Vec<bool> {
    let centre = |i: usize, a: usize| {
        let half = 0.5 * sides[a];
        (2 * i + 1) as f64 * half - dims[a] as f64 * half
    };
    let mut filled = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                filled.push(inside(centre(i, 0), centre(j, 1), centre(k, 2)));
            }
        }
    }
    filled
}

/// The degrees of freedom of a grid: 3 per lattice node that a filled voxel uses.
fn count_dofs(grid: &VoxelGrid) -> usize {
    let [nx, ny, nz] = grid.dims;
    let lattice = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut used = vec![false; (nx + 1) * (ny + 1) * (nz + 1)];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if grid.filled[i + nx * (j + ny * k)] {
                    for c in 0..8 {
                        used[lattice(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))] = true;
                    }
                }
            }
        }
    }
    3 * used.iter().filter(|&&u| u).count()
}

fn positive(shape: &'static str, name: &'static str, value: f64) -> Result<(), ShapeError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ShapeError::BadDimension { shape, name, value })
    }
}

/// A real count as a whole one, saturating.
fn to_count(x: f64) -> usize {
    x.ceil() as usize
}
