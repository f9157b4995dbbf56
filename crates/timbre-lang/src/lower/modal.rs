//! `modal`: the sound of a shape. `(modal :material glass :box (0.3 0.03 0.02))` finds
//! the shape's lowest modes with `timbre_modal` (finite elements of its voxels) and
//! sounds them:
//!
//! - struck once at t = 0, by an impulse of `:impulse` N·s at `:strike` along
//!   `:normal`: `(combine (* A (sine (* t F)) (damp (* t D))))`, the damped sines that
//!   `timbre_ir::optimise` makes one modal bank of;
//! - or driven by a force signal (`:force`, newtons):
//!   `(combine (* G (resonz force F B)))`, each resonator scaled so that an
//!   impulse of J N·s in the force rings as the struck node with `:impulse J` does.
//!
//! A is the pressure of each mode at 1 m over [`FULL_SCALE_PA`] (the convention of
//! the `contacts` presets), F its damped frequency, D = ξω its rate of decay. Modes
//! above 0.45 × the sample rate (the scene's, else 48 kHz), and overdamped ones, are
//! left out. Each analysis is made once per compilation, whatever uses it.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use timbre_diag::Diag;
use timbre_ir::dsp::materials::Material as CatalogueMaterial;
use timbre_ir::keyframes::{Interpolation, KeyframeTrack};
use timbre_ir::op::Op;
use timbre_modal::model::{Damping, Material, ModalError, Model, Settings, Strike};
use timbre_modal::shape::{Resolution, Shape, ShapeError, TriangleMesh};
use timbre_modal::solve::SolveError;
use timbre_modal::Elastic;
use timbre_motion::{NodeIndex, Shot, ShotOptions};
use timbre_syntax::{Expr, ExprKind, Span};

use super::build::{call, driven_bank, symbol, vector};
use super::contacts::FULL_SCALE_PA;
use super::scene::Options;
use super::{Arg, Call, Lowerer, Origin, Scope};
use crate::catalogue::physical::named_material;

/// A light tap, N·s: a 10 g pencil dropped on the object from 1.3 m, or a fingertip's
/// flick.
pub(crate) const DEFAULT_IMPULSE: f64 = 0.01;
/// Modes found when `:modes` is not given.
pub(crate) const DEFAULT_MODES: usize = 32;
/// Modes above this fraction of the sample rate are left out.
const HIGHEST_FRACTION: f64 = 0.45;
/// The sample rate modes are kept below when the scene gives none.
const DEFAULT_RATE: f64 = 48_000.0;

const KEYS: &[&str] = &[
    "mesh", "box", "sphere", "cylinder", "tube", "material", "youngs", "poisson", "density",
    "loss", "alpha", "beta", "modes", "voxel", "strike", "normal", "impulse", "force", "gain",
    "node",
];
const SHAPES: [&str; 5] = ["mesh", "box", "sphere", "cylinder", "tube"];
const SHAPE_HELP: &str = "give one of :mesh \"glass.obj\", :box (x y z), :sphere radius, \
                          :cylinder (radius height) or :tube (outer inner length), in metres";
const USAGE: &str = "(modal :material steel :box (0.3 0.03 0.02) :strike (0.14 0 0.01))";

/// One mode as `timbre check` lists it.
#[derive(Clone, Debug, PartialEq)]
pub struct ModalRow {
    /// The frequency it rings at (damped), Hz.
    pub frequency: f64,
    /// Seconds to decay by 60 dB: 6.91/(ξω).
    pub t60: f64,
    /// Its pressure at 1 m where the shape is struck, dB re the loudest mode's (−∞
    /// where the strike does not excite it).
    pub gain_db: f64,
}

/// What one `modal` node found (listed by `timbre check`).
#[derive(Clone, Debug, PartialEq)]
pub struct FoundModal {
    /// The file and line of the node.
    pub file: String,
    pub line: usize,
    /// The shape as written: "box 0.3 × 0.03 × 0.02 m", "mesh glass.obj".
    pub shape: String,
    /// The material's name, or "custom".
    pub material: String,
    /// Degrees of freedom solved, the voxel's sides along x, y and z (m; a brick
    /// that spans the shape's bounding box) and the mass (kg).
    pub dofs: usize,
    pub voxel: [f64; 3],
    pub mass: f64,
    /// The surface point struck, m, in the shape's coordinates.
    pub strike: [f64; 3],
    /// The modes sounded, lowest first.
    pub modes: Vec<ModalRow>,
    /// Modes found but left out (above 0.45 × the sample rate, or overdamped).
    pub dropped: usize,
    /// The model itself (for pictures of its modes).
    pub model: Arc<Model>,
}

/// The analyses of one compilation, and what `timbre check` lists.
#[derive(Default)]
pub(crate) struct ModalState {
    /// Models by shape, material and settings: a node lowered again (in each
    /// instance of a class) is analysed once.
    models: HashMap<String, Arc<Model>>,
    pub(crate) found: Vec<FoundModal>,
}

/// The one place a model is made: through the cache on disk
/// (`timbre_modal::cache::default_dir`), so a scene renders again without solving.
fn analyse(shape: &Shape, material: &Material, settings: &Settings) -> Result<Model, ModalError> {
    let dir = timbre_modal::cache::default_dir();
    timbre_modal::cache::analyse_cached(shape, material, settings, dir.as_deref()).map(|c| c.model)
}

/// A shape as read from the form, with what a diagnostic needs.
struct ShapeArg<'e> {
    shape: Shape,
    /// Identifies it among analyses (a mesh by its resolved path).
    key: String,
    /// For the listing.
    described: String,
    value: &'e Expr,
}

/// The pieces of a `modal` node's sound, each one lane per mode.
struct Bank {
    frequencies: Vec<f64>,
    decays: Vec<f64>,
    /// Pressure at 1 m per full scale, after the strike.
    amplitudes: Vec<f64>,
}

impl Lowerer<'_> {
    /// `(modal SHAPE :material NAME …)`: see the module docs.
    pub(crate) fn lower_modal(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<timbre_ir::NodeId, Diag> {
        let options = self.options(call.args, "modal", KEYS, origin)?;
        let shape = self.modal_shape(call, &options, origin, scope)?;
        let (material, material_name) = self.modal_material(call, &options, origin, scope)?;
        let modes = match options.get("modes") {
            Some(e) => {
                let arg = self.modal_arg(e, origin, scope)?;
                self.const_count(&arg, "the number of modes", origin)?
            }
            None => DEFAULT_MODES,
        };
        let voxel = match options.get("voxel") {
            Some(e) => Some(self.modal_number(e, "the voxel size", origin, scope)?),
            None => None,
        };
        let settings = Settings {
            modes,
            resolution: Resolution {
                voxel,
                max_dofs: self.options.limits.modal_dofs,
            },
        };
        let model = self.modal_model(call, &shape, &material, &settings, &options, origin)?;
        let strike = self.modal_strike(&model, &options, origin, scope)?;
        let gain = match options.get("gain") {
            Some(e) => self.modal_number(e, "the gain", origin, scope)?,
            None => 1.0,
        };
        let force = options.get("force");
        let impulse = match (options.get("impulse"), force) {
            (Some(e), Some(f)) => {
                return Err(self
                    .diag(
                        "timbre::bad-modal",
                        "`:impulse` and `:force` cannot both be given",
                        origin,
                    )
                    .label(e.span, "a single strike")
                    .label(f.span, "and a force that drives it")
                    .help("a driven shape sounds the impulse its force carries: drop :impulse"))
            }
            (Some(e), None) => self.modal_number(e, "the impulse", origin, scope)?,
            (None, _) => DEFAULT_IMPULSE,
        };
        let (pressures, point) = model.gains(&strike, impulse);
        let rate = self.settings.sample_rate.unwrap_or(DEFAULT_RATE);
        let bank = bank(&model, &pressures, gain / FULL_SCALE_PA, rate);
        self.record_modal(
            call,
            origin,
            shape.described,
            material_name,
            &model,
            point,
            &bank,
        );
        let span = call.span;
        if bank.frequencies.is_empty() {
            self.warn(
                self.diag(
                    "timbre::modal-warning",
                    format!(
                        "every mode of this shape is above {HIGHEST_FRACTION} × the sample \
                         rate ({rate} Hz): it is silent"
                    ),
                    origin,
                )
                .label(span, "silent")
                .help("make the shape larger or softer, or raise the scene's :sample-rate"),
            );
            return Ok(self.graph.constant(0.0));
        }
        match force {
            None => {
                let tree = struck_tree(&bank, span);
                self.lower(&tree, origin, &mut Scope::new())
            }
            Some(force) => {
                let node = self.lower(force, origin, scope)?;
                self.check_one_lane(
                    &Arg {
                        node,
                        span: force.span,
                        given: true,
                    },
                    "the force",
                    origin,
                )?;
                let tree = driven_tree(&bank, impulse, span);
                self.lower(&tree, origin, &mut vec![("force".to_owned(), node)])
            }
        }
    }

    /// A value lowered where it is written.
    fn modal_arg(&mut self, e: &Expr, origin: &Origin, scope: &mut Scope) -> Result<Arg, Diag> {
        let node = self.lower(e, origin, scope)?;
        Ok(Arg {
            node,
            span: e.span,
            given: true,
        })
    }

    fn modal_number(
        &mut self,
        e: &Expr,
        what: &str,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<f64, Diag> {
        let arg = self.modal_arg(e, origin, scope)?;
        self.const_number(&arg, what, origin)
    }

    /// `(x y z)`: `count` constant numbers (a `(vector …)` is read the same).
    fn modal_numbers(
        &mut self,
        e: &Expr,
        count: usize,
        what: &str,
        example: &str,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<Vec<f64>, Diag> {
        let items = match &e.kind {
            ExprKind::List(items) => match items.split_first() {
                Some((head, rest)) if head.as_symbol() == Some("vector") => rest,
                _ => &items[..],
            },
            _ => &[][..],
        };
        if items.len() != count {
            let message = match &e.kind {
                ExprKind::List(_) => format!("{what} takes {count} numbers, not {}", items.len()),
                _ => format!("{what} is a list of {count} numbers, not {}", e.describe()),
            };
            return Err(self
                .diag("timbre::bad-modal", message, origin)
                .label(e.span, format!("expected {count} numbers"))
                .help(format!("write e.g. {example}")));
        }
        let mut values = Vec::with_capacity(count);
        for item in items {
            values.push(self.modal_number(item, what, origin, scope)?);
        }
        Ok(values)
    }

    /// The one shape the node names.
    fn modal_shape<'e>(
        &mut self,
        call: &Call<'_>,
        options: &Options<'e>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<ShapeArg<'e>, Diag> {
        let given: Vec<(&str, &Expr)> = SHAPES
            .iter()
            .filter_map(|&k| options.get(k).map(|e| (k, e)))
            .collect();
        let (kind, value) = match given[..] {
            [one] => one,
            [] => {
                return Err(self
                    .diag("timbre::bad-modal", "`modal` needs a shape", origin)
                    .label(call.span, "no shape")
                    .help(format!("{SHAPE_HELP}: {USAGE}")))
            }
            [(a, first), (b, second), ..] => {
                return Err(self
                    .diag(
                        "timbre::bad-modal",
                        format!("`modal` takes one shape, not :{a} and :{b}"),
                        origin,
                    )
                    .label(first.span, "one shape")
                    .label(second.span, "and another")
                    .help("a node is one solid: sum two `modal` nodes for two"))
            }
        };
        let mut numbers = |this: &mut Self, count, what, example| {
            this.modal_numbers(value, count, what, example, origin, scope)
        };
        let (shape, described) = match kind {
            "box" => {
                let s = numbers(self, 3, "a box's size", "(0.3 0.03 0.02)")?;
                let shape = Shape::Box {
                    size: [s[0], s[1], s[2]],
                };
                (shape, format!("box {} × {} × {} m", s[0], s[1], s[2]))
            }
            "sphere" => {
                let radius = self.modal_number(value, "a sphere's radius", origin, scope)?;
                (Shape::Sphere { radius }, format!("sphere r {radius} m"))
            }
            "cylinder" => {
                let s = numbers(self, 2, "a cylinder's radius and height", "(0.02 0.1)")?;
                let shape = Shape::Cylinder {
                    radius: s[0],
                    height: s[1],
                };
                (shape, format!("cylinder r {} m, {} m high", s[0], s[1]))
            }
            "tube" => {
                let what = "a tube's outer and inner radius and length";
                let s = numbers(self, 3, what, "(0.0125 0.011 0.3)")?;
                let shape = Shape::Tube {
                    outer: s[0],
                    inner: s[1],
                    length: s[2],
                };
                let text = format!("tube r {}/{} m, {} m long", s[0], s[1], s[2]);
                (shape, text)
            }
            _ => {
                let (mesh, resolved, node) = self.modal_mesh(value, options.get("node"), origin)?;
                let mut name = match &value.kind {
                    ExprKind::Str(s) => s.clone(),
                    _ => String::new(),
                };
                if let Some(node) = node {
                    name += &format!(" node {node}");
                }
                let key = format!("mesh {} {name}", resolved.display());
                return Ok(ShapeArg {
                    shape: Shape::Mesh(mesh),
                    key,
                    described: format!("mesh {name}"),
                    value,
                });
            }
        };
        Ok(ShapeArg {
            key: format!("{shape:?}"),
            shape,
            described,
            value,
        })
    }

    /// The mesh of `:mesh "file.obj"`, read through the host's loader (relative to
    /// the file that names it), and its resolved path; or of a glTF file's node (the
    /// one `:node` names, else its only node with a mesh), and the node's name.
    fn modal_mesh(
        &self,
        value: &Expr,
        node: Option<&Expr>,
        origin: &Origin,
    ) -> Result<(TriangleMesh, PathBuf, Option<String>), Diag> {
        let ExprKind::Str(path) = &value.kind else {
            return Err(self
                .diag(
                    "timbre::expected-string",
                    format!("a mesh is a file name, not {}", value.describe()),
                    origin,
                )
                .label(value.span, "expected a string")
                .help("write :mesh \"glass.obj\" (a Wavefront OBJ file), or :mesh \"shot.glb\" :node \"Cup\""));
        };
        let unreadable = |why: String| {
            self.diag(
                "timbre::modal-shape",
                format!("cannot read the mesh file `{path}`: {why}"),
                origin,
            )
            .label(value.span, "this file")
            .help("paths are relative to the file that names them; the file must be a Wavefront OBJ with faces, or a .glb or .gltf with :node")
        };
        let (resolved, bytes) = self
            .options
            .loader
            .load(path, origin.dir.as_deref())
            .map_err(|e| unreadable(e.to_string()))?;
        let lower = path.to_ascii_lowercase();
        if lower.ends_with(".glb") || lower.ends_with(".gltf") {
            let (mesh, name) = self.gltf_mesh(&bytes, &resolved, value, node, origin)?;
            return Ok((mesh, resolved, Some(name)));
        }
        if let Some(node) = node {
            return Err(self
                .diag(
                    "timbre::bad-modal",
                    "`:node` picks a node of a glTF file, not of an OBJ mesh",
                    origin,
                )
                .label(node.span, "a node")
                .label(value.span, "of this file")
                .help("drop :node, or give a .glb or .gltf file"));
        }
        let mesh = TriangleMesh::from_obj_bytes(&bytes).map_err(|e| match e {
            ShapeError::Unreadable { reason, .. } => unreadable(reason),
            other => unreadable(other.to_string()),
        })?;
        Ok((mesh, resolved, None))
    }

    /// The mesh of one node of a glTF file, as [`shot_mesh`] makes it, and the
    /// node's name.
    fn gltf_mesh(
        &self,
        bytes: &[u8],
        resolved: &std::path::Path,
        value: &Expr,
        node: Option<&Expr>,
        origin: &Origin,
    ) -> Result<(TriangleMesh, String), Diag> {
        let shot = self
            .read_shot(bytes, resolved, &ShotOptions::default())
            .map_err(|e| e.diag(value.span).in_source(&origin.source))?;
        let with_meshes: Vec<&str> = shot
            .node_names()
            .filter(|n| shot.node(n).is_some_and(|i| shot.mesh(i).is_some()))
            .collect();
        let name = match node {
            Some(e) => match &e.kind {
                ExprKind::Str(name) => name.clone(),
                _ => {
                    return Err(self
                        .diag(
                            "timbre::expected-string",
                            format!("a node is named by a string, not {}", e.describe()),
                            origin,
                        )
                        .label(e.span, "expected a string")
                        .help("write :node \"Cube\", a node of the file with a mesh"))
                }
            },
            None => match with_meshes[..] {
                [one] => one.to_owned(),
                _ => {
                    return Err(self
                        .diag(
                            "timbre::bad-modal",
                            format!(
                                "the file has {} nodes with meshes: name one with :node",
                                with_meshes.len()
                            ),
                            origin,
                        )
                        .label(value.span, "which mesh?")
                        .help(format!("its nodes with meshes: {}", with_meshes.join(", "))))
                }
            },
        };
        let span = node.map_or(value.span, |e| e.span);
        let Some(mesh) = shot.node(&name).and_then(|i| shot_mesh(&shot, i)) else {
            let help = match super::did_you_mean(&name, with_meshes.iter().copied()) {
                Some(close) => format!("did you mean \"{close}\"?"),
                None => format!("its nodes with meshes: {}", with_meshes.join(", ")),
            };
            return Err(self
                .diag(
                    "timbre::unknown-node",
                    format!("the file has no node \"{name}\" with a mesh"),
                    origin,
                )
                .label(span, "not in the file")
                .help(help));
        };
        Ok((mesh, name))
    }

    /// The material: a named one, its constants overridden by any given, or
    /// constants alone; damping by loss factor or Rayleigh's α and β.
    fn modal_material(
        &mut self,
        call: &Call<'_>,
        options: &Options<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<(Material, String), Diag> {
        let named = match options.get("material") {
            Some(e) => Some(named_material(self, e, origin)?),
            None => None,
        };
        let mut constant =
            |this: &mut Self, key: &str, what: &str, from: Option<f64>| match options.get(key) {
                Some(e) => this.modal_number(e, what, origin, scope).map(Some),
                None => Ok(from),
            };
        let youngs = constant(self, "youngs", "Young's modulus", named.map(|m| m.youngs))?;
        let poisson = constant(self, "poisson", "Poisson's ratio", named.map(|m| m.poisson))?;
        let density = constant(self, "density", "the density", named.map(|m| m.density))?;
        let loss = constant(self, "loss", "the loss factor", named.map(|m| m.loss))?;
        let alpha = constant(self, "alpha", "Rayleigh's α", None)?;
        let beta = constant(self, "beta", "Rayleigh's β", None)?;
        let (Some(youngs), Some(poisson), Some(density)) = (youngs, poisson, density) else {
            return Err(self
                .diag(
                    "timbre::bad-modal",
                    "`modal` needs a material: :material NAME, or :youngs, :poisson and :density",
                    origin,
                )
                .label(call.span, "no material")
                .help(
                    "e.g. :material glass, or :youngs 70e9 :poisson 0.22 :density 2500 :loss 0.001",
                ));
        };
        let rayleigh = alpha.is_some() || beta.is_some();
        let damping = match (rayleigh, options.get("loss"), loss) {
            (true, Some(e), _) => {
                return Err(self
                    .diag(
                        "timbre::bad-modal",
                        "give a loss factor or Rayleigh damping, not both",
                        origin,
                    )
                    .label(e.span, "a loss factor")
                    .help("ξ = η/2 with :loss η, or ξ = α/(2ω) + βω/2 with :alpha and :beta"));
            }
            (true, None, _) => Damping::Rayleigh {
                alpha: alpha.unwrap_or(0.0),
                beta: beta.unwrap_or(0.0),
            },
            (false, _, Some(loss)) => Damping::Loss(loss),
            (false, _, None) => {
                return Err(self
                    .diag("timbre::bad-modal", "`modal` needs a damping", origin)
                    .label(call.span, "no damping")
                    .help("give :loss η (e.g. 0.001), or Rayleigh's :alpha and :beta"))
            }
        };
        let elastic = Elastic {
            youngs,
            poisson,
            density,
        };
        let name = match named {
            Some(m) if [youngs, poisson, density] == [m.youngs, m.poisson, m.density] => {
                m.name.to_owned()
            }
            _ => "custom".to_owned(),
        };
        Ok((Material { elastic, damping }, name))
    }

    /// The shape's model, analysed once per compilation; its warnings reported.
    fn modal_model(
        &mut self,
        call: &Call<'_>,
        shape: &ShapeArg<'_>,
        material: &Material,
        settings: &Settings,
        options: &Options<'_>,
        origin: &Origin,
    ) -> Result<Arc<Model>, Diag> {
        let key = format!("{} {material:?} {settings:?}", shape.key);
        let model = self
            .shared_model(key, &shape.shape, material, settings, call.span, origin)?
            .map_err(|e| self.modal_error(e, call, shape, options, origin))?;
        self.modal_warnings(&model, shape.value.span, origin);
        Ok(model)
    }

    /// The model of `shape`, analysed once per compilation whatever asks for it
    /// (`key` tells shapes, materials and settings apart). The outer error is the
    /// load's time limit, reached before solving (at `span`).
    pub(crate) fn shared_model(
        &mut self,
        key: String,
        shape: &Shape,
        material: &Material,
        settings: &Settings,
        span: Span,
        origin: &Origin,
    ) -> Result<Result<Arc<Model>, ModalError>, Diag> {
        if let Some(model) = self.modal.models.get(&key) {
            return Ok(Ok(model.clone()));
        }
        self.check_load_time(span, origin)?;
        Ok(analyse(shape, material, settings).map(|model| {
            let model = Arc::new(model);
            self.modal.models.insert(key, model.clone());
            model
        }))
    }

    /// Reports a model's warnings (the voxelisation's, pieces dropped) at `span`.
    pub(crate) fn modal_warnings(&mut self, model: &Model, span: Span, origin: &Origin) {
        for warning in &model.warnings {
            let help = if warning.contains("gives 2") {
                "set :voxel to the size it names for bending modes within 1 % (a finer grid, a longer solve)"
            } else if warning.contains("pieces") {
                "only the largest piece sounds: join the parts, or give each its own `modal`"
            } else {
                "the solid was made anyway; close the mesh for one that is sure"
            };
            let diag = self
                .diag("timbre::modal-warning", warning.clone(), origin)
                .label(span, "this shape")
                .help(help);
            self.warn(diag);
        }
    }

    /// The sound of `model` struck at `strike` by the force bound to `force` (N):
    /// `(combine (* G (resonz force F B)))`, an impulse of J N·s in the force
    /// ringing as a strike of J does, times `gain`. `None` when every mode is above
    /// 0.45 × the sample rate.
    pub(crate) fn driven_model(
        &self,
        model: &Model,
        strike: &Strike,
        gain: f64,
        span: Span,
    ) -> Option<Expr> {
        let (pressures, _) = model.gains(strike, 1.0);
        let rate = self.settings.sample_rate.unwrap_or(DEFAULT_RATE);
        let bank = bank(model, &pressures, gain / FULL_SCALE_PA, rate);
        (!bank.frequencies.is_empty()).then(|| driven_tree(&bank, 1.0, span))
    }

    /// The sound of `model` struck where a sustained contact is at each of its keys
    /// (`strikes[i]` at `times[i]`, scene seconds, read by an instance lowered at
    /// `self.time_offset`), by the force bound to `force` (N), times `gain`:
    /// `(combine (* S (resonz (* force gains) F B)))`. The modal force on mode k is
    /// φₖ(p(t))·d(t)·f(t), so the gain moves on the resonator's input (a mode keeps
    /// ringing with the gain of where it was struck): `gains` is one track per mode
    /// of its pressure at 1 m per N·s where the contact is at each key, moving
    /// linearly between keys (a constant where it never changes), and
    /// S = gain/(full scale·2π·B) as in [`Self::driven_model`]. Returns the tree and
    /// the names it reads besides `force`; a contact whose gains never change is
    /// `driven_model`'s tree. `None` when every mode is above 0.45 × the sample
    /// rate, or there are no keys.
    pub(crate) fn moving_driven_model(
        &mut self,
        model: &Model,
        times: &[f64],
        strikes: &[Strike],
        gain: f64,
        span: Span,
    ) -> Option<(Expr, Scope)> {
        let rate = self.settings.sample_rate.unwrap_or(DEFAULT_RATE);
        // Each key's pressures, of the modes that sound, in the bank's order.
        let keyed: Vec<Vec<f64>> = strikes
            .iter()
            .map(|strike| bank(model, &model.gains(strike, 1.0).0, 1.0, rate).amplitudes)
            .collect();
        let first = keyed.first()?;
        if keyed.iter().all(|k| k == first) {
            let tree = self.driven_model(model, strikes.first()?, gain, span)?;
            return Some((tree, Scope::new()));
        }
        let units = vec![1.0; model.modes.len()];
        let scales = bank(model, &units, gain / FULL_SCALE_PA, rate);
        let mut lanes = Vec::with_capacity(first.len());
        for mode in 0..first.len() {
            let values: Vec<f64> = keyed.iter().map(|k| k[mode]).collect();
            let moves = values.iter().any(|v| *v != values[0]);
            // Keys the force's own tracks would refuse too never come here.
            let track = moves
                .then(|| KeyframeTrack::new(times.to_vec(), values, Interpolation::Linear).ok())
                .flatten();
            lanes.push(match track {
                Some(track) => self.keyframe_node(Arc::new(track)),
                None => self.graph.constant(first[mode]),
            });
        }
        let gains = self.graph.add(Op::Concat, lanes);
        let input = call(
            "*",
            vec![symbol("force", span), symbol("gains", span)],
            span,
        );
        let tree = driven_tree_of(input, &scales, 1.0, span);
        Some((tree, vec![("gains".to_owned(), gains)]))
    }

    /// A diagnostic for an analysis that failed.
    fn modal_error(
        &self,
        error: ModalError,
        call: &Call<'_>,
        shape: &ShapeArg<'_>,
        options: &Options<'_>,
        origin: &Origin,
    ) -> Diag {
        let message = error.to_string();
        let voxel_span = options.get("voxel").map_or(call.span, |e| e.span);
        let fits = |voxel: &Option<f64>| match voxel {
            Some(v) => format!("a voxel of {v:.3e} m fits: write :voxel {v:.3e}"),
            None => "no voxel size fits: make the shape smaller or simpler".to_owned(),
        };
        let (code, span, label, help) = match &error {
            ModalError::Shape(ShapeError::TooManyDofs { fitting_voxel, .. })
            | ModalError::Shape(ShapeError::GridTooLarge { fitting_voxel, .. }) => (
                "timbre::modal-shape",
                voxel_span,
                "too fine a grid",
                fits(fitting_voxel),
            ),
            ModalError::Shape(ShapeError::BadVoxel { .. }) => (
                "timbre::modal-shape",
                voxel_span,
                "not a voxel size",
                "a voxel is a length in metres above 0, e.g. :voxel 0.002".to_owned(),
            ),
            ModalError::Shape(ShapeError::NothingFilled { suggested, .. }) => (
                "timbre::modal-shape",
                voxel_span,
                "too coarse a grid",
                format!("write :voxel {suggested:.3e} or smaller"),
            ),
            ModalError::Shape(_) => (
                "timbre::modal-shape",
                shape.value.span,
                "this shape",
                SHAPE_HELP.to_owned(),
            ),
            ModalError::Solve(SolveError::NoConvergence { .. }) => (
                "timbre::modal-solve",
                call.span,
                "these modes",
                "ask for fewer :modes, or another :voxel".to_owned(),
            ),
            ModalError::Solve(SolveError::TooSmall { .. }) => (
                "timbre::modal-solve",
                call.span,
                "too few voxels",
                "ask for fewer :modes, or a smaller :voxel".to_owned(),
            ),
            ModalError::Solve(_) => (
                "timbre::modal-solve",
                call.span,
                "this shape",
                "check the material's constants; ask for fewer :modes".to_owned(),
            ),
            ModalError::Material(..) | ModalError::NoModes => (
                "timbre::bad-modal",
                options
                    .get("material")
                    .or(options.get("youngs"))
                    .map_or(call.span, |e| e.span),
                "this material",
                "Young's modulus and density above 0, Poisson's ratio in (−1, 0.5), damping ≥ 0"
                    .to_owned(),
            ),
        };
        self.diag(code, message, origin)
            .label(span, label)
            .help(help)
    }

    /// Where and along what the shape is struck: `:strike` and `:normal` (default
    /// −z), or the model's default strike.
    fn modal_strike(
        &mut self,
        model: &Model,
        options: &Options<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<Strike, Diag> {
        let mut strike = model.default_strike();
        if let Some(e) = options.get("strike") {
            let p = self.modal_numbers(e, 3, "the point struck", "(0.14 0 0.01)", origin, scope)?;
            strike.point = [p[0], p[1], p[2]];
        }
        if let Some(e) = options.get("normal") {
            let d = self.modal_numbers(e, 3, "the direction struck", "(0 0 -1)", origin, scope)?;
            if d.iter().all(|x| *x == 0.0) {
                return Err(self
                    .diag("timbre::bad-modal", "the normal has no direction", origin)
                    .label(e.span, "(0 0 0)")
                    .help("the direction of the blow, e.g. (0 0 -1): down, into the top"));
            }
            strike.direction = [d[0], d[1], d[2]];
        }
        Ok(strike)
    }

    /// Keeps what `timbre check` lists, once per node written.
    #[allow(clippy::too_many_arguments)]
    fn record_modal(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        shape: String,
        material: String,
        model: &Arc<Model>,
        point: [f64; 3],
        bank: &Bank,
    ) {
        let file = origin.source.name.clone();
        let text = &origin.source.text;
        let line = 1 + text[..call.span.start.min(text.len())]
            .bytes()
            .filter(|b| *b == b'\n')
            .count();
        if self
            .modal
            .found
            .iter()
            .any(|f| f.file == file && f.line == line)
        {
            return;
        }
        let loudest = bank.amplitudes.iter().fold(0.0, |m: f64, a| m.max(a.abs()));
        let modes = bank
            .frequencies
            .iter()
            .zip(&bank.decays)
            .zip(&bank.amplitudes)
            .map(|((&frequency, &decay), &a)| ModalRow {
                frequency,
                t60: 3.0 * std::f64::consts::LN_10 / decay,
                gain_db: 20.0 * (a.abs() / loudest).log10(),
            })
            .collect::<Vec<_>>();
        self.modal.found.push(FoundModal {
            file,
            line,
            shape,
            material,
            dofs: model.dofs,
            voxel: model.surface.sides,
            mass: model.mass,
            strike: point,
            dropped: model.modes.len() - modes.len(),
            modes,
            model: model.clone(),
        });
    }
}

/// The material `modal` makes of one of the catalogue's (those `contacts` names):
/// its elastic constants, damped by its loss factor.
pub(crate) fn catalogue_material(material: &CatalogueMaterial) -> Material {
    Material {
        elastic: Elastic {
            youngs: material.youngs,
            poisson: material.poisson,
            density: material.density,
        },
        damping: Damping::Loss(material.loss),
    }
}

/// The mesh of a shot's node, as `modal` and `contacts` analyse it: scaled by the
/// node's world scale at time 0, in the node's own frame (timbre axes).
pub(crate) fn shot_mesh(shot: &Shot, node: NodeIndex) -> Option<TriangleMesh> {
    let mesh = shot.mesh(node)?;
    let scale = shot.pose(node, 0.0).scale;
    Some(TriangleMesh {
        positions: mesh
            .vertices
            .iter()
            .map(|&v| (v * scale).to_array())
            .collect(),
        triangles: mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| i as usize))
            .collect(),
    })
}

/// The code of a diagnostic for an analysis that failed.
pub(crate) fn modal_code(error: &ModalError) -> &'static str {
    match error {
        ModalError::Shape(_) => "timbre::modal-shape",
        ModalError::Solve(_) => "timbre::modal-solve",
        ModalError::Material(..) | ModalError::NoModes => "timbre::bad-modal",
    }
}

/// The modes that sound at `rate`, with their pressures at 1 m times `scale`.
fn bank(model: &Model, pressures: &[f64], scale: f64, rate: f64) -> Bank {
    let mut bank = Bank {
        frequencies: vec![],
        decays: vec![],
        amplitudes: vec![],
    };
    for (mode, pressure) in model.modes.iter().zip(pressures) {
        let frequency = mode.damped_frequency();
        if frequency > 0.0 && frequency <= HIGHEST_FRACTION * rate {
            bank.frequencies.push(frequency);
            bank.decays.push(mode.decay());
            bank.amplitudes.push(pressure * scale);
        }
    }
    bank
}

/// `(combine (* A (sine (* t F)) (damp (* t D))))`.
fn struck_tree(bank: &Bank, span: Span) -> Expr {
    let times = |values: &[f64]| call("*", vec![symbol("t", span), vector(values, span)], span);
    let sine = call("sine", vec![times(&bank.frequencies)], span);
    let damp = call("damp", vec![times(&bank.decays)], span);
    let product = call("*", vec![vector(&bank.amplitudes, span), sine, damp], span);
    call("combine", vec![product], span)
}

/// `(combine (* G (resonz force F B)))`. A resonator of unit peak gain and
/// bandwidth B rings after an impulse J (a force of J·sr for one sample) with an
/// envelope of 2π·B·J·e^(−π·B·t) (lang-spec/nodes.md, `resonz`); with B = D/π
/// it decays as the struck mode does, and G = A/(2π·B·J) gives it the struck
/// amplitude A.
fn driven_tree(bank: &Bank, impulse: f64, span: Span) -> Expr {
    driven_tree_of(symbol("force", span), bank, impulse, span)
}

/// [`driven_tree`] with its resonators driven by `input` (one lane, or one per
/// mode) instead of the force.
fn driven_tree_of(input: Expr, bank: &Bank, impulse: f64, span: Span) -> Expr {
    // `resonz` clamps its bandwidth to 0.001 Hz: an undamped mode rings that long.
    let bandwidths: Vec<f64> = bank
        .decays
        .iter()
        .map(|d| (d / std::f64::consts::PI).max(0.001))
        .collect();
    let gains: Vec<f64> = bank
        .amplitudes
        .iter()
        .zip(&bandwidths)
        .map(|(a, b)| a / (2.0 * std::f64::consts::PI * b * impulse))
        .collect();
    driven_bank(input, &gains, &bank.frequencies, &bandwidths, span)
}
