//! What voxelising a shape can warn about or refuse, each a full English sentence
//! with the numbers a help line needs (a voxel size that would do).

use std::fmt;
use std::path::PathBuf;

/// Something about a shape or its grid that did not stop the voxelisation.
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeWarning {
    /// Edges used by one triangle only: the mesh has holes.
    OpenMesh { edges: usize },
    /// Edges used by more than two triangles.
    NonManifold { edges: usize },
    /// Voxels that one or two of the three axes found inside, decided by the vote.
    RaysDisagreed {
        voxels: usize,
        /// The filled voxels, for the fraction.
        filled: usize,
    },
    /// No inward ray hit another surface, so the thinnest wall was taken as the
    /// smallest side of the bounding box.
    WallGuessed { wall: f64 },
    /// Fewer than [`crate::shape::WALL_VOXELS`] voxels through the thinnest wall:
    /// bending modes come out too high.
    TooThin {
        /// The wall with the fewest voxels across (a primitive's thickness along
        /// one axis, a mesh's thinnest wall), m.
        wall: f64,
        /// The brick's side across the wall, m.
        voxel: f64,
        /// How many bricks cross the wall.
        voxels_across: f64,
        /// The voxel size that puts 2 across every wall.
        voxel_for_wall: f64,
        /// The degrees of freedom that size would take (estimated).
        dofs_for_wall: usize,
    },
}

/// Why a shape could not be voxelised.
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeError {
    /// The mesh file could not be read or parsed (the path is empty for bytes given).
    Unreadable { path: PathBuf, reason: String },
    /// The mesh has no triangles.
    NoTriangles,
    /// A vertex with a coordinate that is infinite or not a number.
    NonFiniteVertex { vertex: usize },
    /// A triangle naming a vertex the mesh does not have.
    VertexOutOfRange {
        triangle: usize,
        index: usize,
        vertices: usize,
    },
    /// The mesh has no extent along an axis (0, 1, 2 for x, y, z): a sheet, not a solid.
    Flat { axis: usize, extent: f64 },
    /// A primitive's dimension that is not a positive, finite length.
    BadDimension {
        shape: &'static str,
        name: &'static str,
        value: f64,
    },
    /// A tube whose inner radius is not smaller than its outer one.
    InnerNotBelowOuter { inner: f64, outer: f64 },
    /// A voxel size that is not a positive, finite length.
    BadVoxel { value: f64 },
    /// No voxel centre fell inside the shape.
    NothingFilled { voxel: f64, suggested: f64 },
    /// The grid would take more degrees of freedom than allowed.
    TooManyDofs {
        voxel: f64,
        estimated: usize,
        limit: usize,
        /// A voxel size whose grid fits the limit (by the estimate, or scaled from the
        /// count as 1/h³ when the filled grid was over); None when none does.
        fitting_voxel: Option<f64>,
    },
    /// The grid around the shape would hold more than
    /// [`MAX_GRID_VOXELS`](super::MAX_GRID_VOXELS) voxels.
    GridTooLarge {
        voxel: f64,
        voxels: f64,
        limit: usize,
        fitting_voxel: Option<f64>,
    },
}

impl std::error::Error for ShapeError {}

fn edges_belong(edges: usize) -> String {
    if edges == 1 {
        "1 edge belongs".to_string()
    } else {
        format!("{edges} edges belong")
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// A length for people: in m, mm or µm, to 4 significant digits.
fn length(metres: f64) -> String {
    let (value, unit) = if metres.abs() >= 1.0 {
        (metres, "m")
    } else if metres.abs() >= 1e-3 {
        (metres * 1e3, "mm")
    } else {
        (metres * 1e6, "µm")
    };
    let decimals = (3 - value.abs().log10().floor() as i32).clamp(0, 6) as usize;
    let text = format!("{value:.decimals$}");
    let text = if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        &text
    };
    format!("{text} {unit}")
}

impl fmt::Display for ShapeWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ShapeWarning::OpenMesh { edges } => write!(
                f,
                "the mesh is open: {} to one triangle only; rays that passed through a \
                 hole abstained and the other axes decided, so small holes are closed over",
                edges_belong(edges)
            ),
            ShapeWarning::NonManifold { edges } => write!(
                f,
                "the mesh is not manifold: {} to more than two triangles; inside and \
                 outside were decided by winding numbers along rays, which joins \
                 overlapping parts into one solid",
                edges_belong(edges)
            ),
            ShapeWarning::RaysDisagreed { voxels, filled } => write!(
                f,
                "the rays along x, y and z did not agree on {voxels} voxels ({:.1} % of \
                 the {filled} filled); each was decided by a majority of the axes",
                100.0 * voxels as f64 / filled.max(1) as f64
            ),
            ShapeWarning::WallGuessed { wall } => write!(
                f,
                "no ray from the surface inward hit another surface (an open sheet?), so \
                 the thinnest wall was taken as the smallest side of the bounding box, {}",
                length(wall)
            ),
            ShapeWarning::TooThin {
                wall,
                voxel,
                voxels_across,
                voxel_for_wall,
                dofs_for_wall,
            } => write!(
                f,
                "a wall {} thick is only {voxels_across:.1} voxels across, each {} \
                 long across it; with fewer than 2 the wall is a sheet of voxels joined at \
                 their edges, and its bending modes come out too high: a voxel of {} \
                 gives 2, at about {dofs_for_wall} degrees of freedom",
                length(wall),
                length(voxel),
                length(voxel_for_wall)
            ),
        }
    }
}

impl fmt::Display for ShapeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ShapeError::Unreadable { path, reason } if path.as_os_str().is_empty() => {
                write!(f, "cannot read the mesh: {reason}")
            }
            ShapeError::Unreadable { path, reason } => {
                write!(
                    f,
                    "cannot read the mesh file `{}`: {reason}",
                    path.display()
                )
            }
            ShapeError::NoTriangles => write!(
                f,
                "the mesh has no triangles; a solid needs a closed surface of faces \
                 (`f` lines in an OBJ file)"
            ),
            ShapeError::NonFiniteVertex { vertex } => write!(
                f,
                "vertex {vertex} of the mesh has a coordinate that is infinite or not a number"
            ),
            ShapeError::VertexOutOfRange {
                triangle,
                index,
                vertices,
            } => write!(
                f,
                "triangle {triangle} of the mesh uses vertex {index}, but the mesh has \
                 {vertices} vertices"
            ),
            ShapeError::Flat { axis, extent } => write!(
                f,
                "the mesh is flat: it spans {} along {}, so it encloses no volume; a \
                 vibrating solid needs a thickness",
                length(*extent),
                AXES[*axis]
            ),
            ShapeError::BadDimension { shape, name, value } => write!(
                f,
                "the {shape}'s {name} must be a positive, finite length in metres, not {value}"
            ),
            ShapeError::InnerNotBelowOuter { inner, outer } => write!(
                f,
                "the tube's inner radius, {}, is not smaller than its outer radius, {}; \
                 its wall would be empty (an inner radius of 0 makes a rod)",
                length(*inner),
                length(*outer)
            ),
            ShapeError::BadVoxel { value } => write!(
                f,
                "the voxel size must be a positive, finite length in metres, not {value}"
            ),
            ShapeError::NothingFilled { voxel, suggested } => write!(
                f,
                "no voxel centre falls inside the shape at a voxel size of {}; a voxel of \
                 {} (bricks at most half its thinnest wall) would fill it",
                length(*voxel),
                length(*suggested)
            ),
            ShapeError::TooManyDofs {
                voxel,
                estimated,
                limit,
                fitting_voxel,
            } => {
                write!(
                    f,
                    "a voxel size of {} would take about {estimated} degrees of freedom, \
                     over the limit of {limit}",
                    length(*voxel)
                )?;
                match fitting_voxel {
                    Some(fit) => write!(f, "; a voxel of {} fits", length(*fit)),
                    None => write!(f, "; no grid fits (one voxel takes 24)"),
                }
            }
            ShapeError::GridTooLarge {
                voxel,
                voxels,
                limit,
                fitting_voxel,
            } => {
                write!(
                    f,
                    "the grid around the shape would hold {voxels:.3e} voxels at a voxel \
                     size of {}, over the limit of {limit}",
                    length(*voxel)
                )?;
                match fitting_voxel {
                    Some(fit) => write!(f, "; a voxel of {} fits", length(*fit)),
                    None => write!(f, "; no grid fits"),
                }
            }
        }
    }
}
