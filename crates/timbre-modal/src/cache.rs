//! Models kept on disk, so a shot renders again without solving again.
//!
//! A model is filed under the SHA-256 of everything its modes depend on: this
//! format's version, the shape (its kind and dimensions, or every vertex and
//! triangle of its mesh), the elastic constants, the number of modes and the
//! resolution. Damping is not in the key: it changes no mode shape, and is applied
//! again on loading. A file is written whole under a temporary name and renamed, so
//! an interrupted write leaves no partial model; a file that does not read back
//! (truncated, from another version) is solved again and replaced.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::grid::ExposedFace;
use crate::model::Material;
use crate::model::{ModalError, Mode, Model, Settings, Surface};
use crate::shape::Shape;

/// The first bytes of a cached model, with the format's version.
const MAGIC: &[u8; 16] = b"timbre-modal\0\0\0\x03";

/// A model and whether it came from the cache.
#[derive(Clone, Debug)]
pub struct Cached {
    pub model: Model,
    /// True when read from the cache, false when solved (and then stored).
    pub loaded: bool,
}

/// Where models are cached: `$TIMBRE_CACHE_DIR/modal`, or
/// `$XDG_CACHE_HOME/timbre/modal`, or `~/.cache/timbre/modal`; None without any.
pub fn default_dir() -> Option<PathBuf> {
    let var = |name| {
        std::env::var_os(name)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(dir) = var("TIMBRE_CACHE_DIR") {
        return Some(dir.join("modal"));
    }
    if let Some(dir) = var("XDG_CACHE_HOME") {
        return Some(dir.join("timbre").join("modal"));
    }
    var("HOME").map(|home| home.join(".cache").join("timbre").join("modal"))
}

/// [`Model::analyse`], through the cache in `dir` when given. A cache that cannot be
/// read or written is passed by: the model is solved (and the error is not the
/// caller's).
pub fn analyse_cached(
    shape: &Shape,
    material: &Material,
    settings: &Settings,
    dir: Option<&Path>,
) -> Result<Cached, ModalError> {
    let Some(dir) = dir else {
        return Model::analyse(shape, material, settings).map(|model| Cached {
            model,
            loaded: false,
        });
    };
    let path = dir.join(format!("{}.modal", key(shape, material, settings)));
    if let Some(model) = std::fs::read(&path).ok().and_then(|bytes| decode(&bytes)) {
        return Ok(Cached {
            model: model.with_damping(material.damping),
            loaded: true,
        });
    }
    let model = Model::analyse(shape, material, settings)?;
    let _ = store(&path, &encode(&model));
    Ok(Cached {
        model,
        loaded: false,
    })
}

/// The hex SHA-256 of what a model depends on.
pub fn key(shape: &Shape, material: &Material, settings: &Settings) -> String {
    let mut hash = Sha256::new();
    hash.update(MAGIC);
    let mut numbers = |xs: &[f64]| xs.iter().for_each(|x| hash.update(x.to_le_bytes()));
    match shape {
        Shape::Box { size } => {
            numbers(&[1.0]);
            numbers(size);
        }
        Shape::Sphere { radius } => numbers(&[2.0, *radius]),
        Shape::Cylinder { radius, height } => numbers(&[3.0, *radius, *height]),
        Shape::Tube {
            outer,
            inner,
            length,
        } => numbers(&[4.0, *outer, *inner, *length]),
        Shape::Mesh(mesh) => {
            numbers(&[
                5.0,
                mesh.positions.len() as f64,
                mesh.triangles.len() as f64,
            ]);
            mesh.positions.iter().for_each(|p| numbers(p));
            mesh.triangles
                .iter()
                .for_each(|t| numbers(&t.map(|i| i as f64)));
        }
    }
    let e = &material.elastic;
    numbers(&[e.youngs, e.poisson, e.density, settings.modes as f64]);
    numbers(&[
        settings.resolution.voxel.unwrap_or(-1.0),
        settings.resolution.max_dofs as f64,
    ]);
    hash.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Writes `bytes` to `path` through a temporary file in the same directory.
fn store(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let temporary = path.with_extension(format!("partial-{}", std::process::id()));
    std::fs::write(&temporary, bytes)?;
    std::fs::rename(&temporary, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&temporary);
    })
}

fn encode(model: &Model) -> Vec<u8> {
    let mut out = MAGIC.to_vec();
    let u64s = |out: &mut Vec<u8>, xs: &[u64]| xs.iter().for_each(|x| out.extend(x.to_le_bytes()));
    u64s(&mut out, &[model.dofs as u64]);
    let f64s = |out: &mut Vec<u8>, xs: &[f64]| xs.iter().for_each(|x| out.extend(x.to_le_bytes()));
    f64s(&mut out, &[model.mass]);
    f64s(&mut out, &model.bounds.0);
    f64s(&mut out, &model.bounds.1);
    u64s(&mut out, &[model.modes.len() as u64]);
    for mode in &model.modes {
        f64s(&mut out, &[mode.frequency, mode.radiation]);
    }
    let surface = &model.surface;
    f64s(&mut out, &surface.sides);
    u64s(&mut out, &[surface.faces.len() as u64]);
    for face in &surface.faces {
        u64s(&mut out, &face.corners.map(|c| c as u64));
        u64s(&mut out, &[face.axis as u64, (face.outward > 0) as u64]);
        f64s(&mut out, &face.low);
    }
    u64s(&mut out, &[surface.points.len() as u64]);
    surface.points.iter().for_each(|p| f64s(&mut out, p));
    u64s(&mut out, &[surface.shapes.len() as u64]);
    surface
        .shapes
        .iter()
        .for_each(|x| out.extend(x.to_le_bytes()));
    u64s(&mut out, &[model.warnings.len() as u64]);
    for warning in &model.warnings {
        u64s(&mut out, &[warning.len() as u64]);
        out.extend(warning.as_bytes());
    }
    out
}

/// Reads what [`encode`] wrote; None on anything else. Damping is left 0.
fn decode(bytes: &[u8]) -> Option<Model> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(MAGIC.len())? != MAGIC {
        return None;
    }
    let dofs = r.u64()? as usize;
    let mass = r.f64()?;
    let low = [r.f64()?, r.f64()?, r.f64()?];
    let high = [r.f64()?, r.f64()?, r.f64()?];
    let count = r.length(16)?;
    let mut modes = Vec::with_capacity(count);
    for _ in 0..count {
        let (frequency, radiation) = (r.f64()?, r.f64()?);
        modes.push(Mode {
            frequency,
            damping: 0.0,
            radiation,
        });
    }
    let sides = [r.f64()?, r.f64()?, r.f64()?];
    let faces_count = r.length(72)?;
    let mut faces = Vec::with_capacity(faces_count);
    for _ in 0..faces_count {
        let corners = [r.u64()?, r.u64()?, r.u64()?, r.u64()?].map(|c| c as usize);
        let (axis, outward) = (r.u64()? as usize, r.u64()?);
        let low = [r.f64()?, r.f64()?, r.f64()?];
        faces.push(ExposedFace {
            corners,
            axis: axis.min(2),
            outward: if outward == 1 { 1 } else { -1 },
            low,
        });
    }
    let points_count = r.length(24)?;
    let mut points = Vec::with_capacity(points_count);
    for _ in 0..points_count {
        points.push([r.f64()?, r.f64()?, r.f64()?]);
    }
    let shapes_count = r.length(4)?;
    let mut shapes = Vec::with_capacity(shapes_count);
    for _ in 0..shapes_count {
        shapes.push(f32::from_le_bytes(r.take(4)?.try_into().ok()?));
    }
    let warnings_count = r.length(8)?;
    let mut warnings = Vec::with_capacity(warnings_count);
    for _ in 0..warnings_count {
        let length = r.length(1)?;
        warnings.push(String::from_utf8(r.take(length)?.to_vec()).ok()?);
    }
    // Every index in range, and nothing left over.
    let consistent = r.at == bytes.len()
        && shapes.len() == points.len() * modes.len() * 3
        && faces
            .iter()
            .all(|f| f.corners.iter().all(|&c| c < points.len()));
    consistent.then_some(Model {
        modes,
        dofs,
        mass,
        bounds: (low, high),
        surface: Surface {
            sides,
            faces,
            points,
            shapes,
        },
        warnings,
    })
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let end = self.at.checked_add(n)?;
        let out = self.bytes.get(self.at..end)?;
        self.at = end;
        Some(out)
    }

    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }

    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }

    /// A count of items of `size` bytes each that the rest of the file can hold.
    fn length(&mut self, size: usize) -> Option<usize> {
        let n = usize::try_from(self.u64()?).ok()?;
        (n.checked_mul(size)? <= self.bytes.len() - self.at).then_some(n)
    }
}
