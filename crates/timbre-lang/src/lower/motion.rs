//! Motion from animated glTF files and keyframed vectors: the `motion` form, and the
//! nodes that read quantities of motion (`position`, `velocity`, `acceleration`,
//! `speed`, `distance`, `approach`, `angular-velocity`, `angular-speed`, `forward`,
//! `up`, `scale`).
//!
//! `(motion shot "car-pass.glb" :animation "Drive" :start 0)` reads the file through
//! the loader (and its external buffers the same way) with `timbre-motion`, and
//! makes each of its nodes available by its glTF name in quotes: `(position "Ball")`.
//! A quantity's argument is a *track*: a node's name, a keyframed vector variable, or
//! `(position …)`, `(forward "N")`, `(up "N")`, `(angular-velocity "N")` of one.
//! The quantities are exact derivatives of the interpolants (see
//! `timbre_ir::motion`); they are not forms, so a class may still name a parameter
//! `speed`.

use std::sync::Arc;

use timbre_diag::Diag;
use timbre_ir::motion::{
    Difference, KeyedTrajectory, MotionKernel, Quantity, Shifted, Trajectory, Written,
};
use timbre_ir::op::{BinaryOp, Op};
use timbre_ir::NodeId;
use timbre_motion::{NodeIndex, Shot, ShotOptions};
use timbre_syntax::{Expr, ExprKind, Span};

use super::{Arg, Call, Lowerer, Origin, Scope};

/// The nodes that read motion, for did-you-mean and completion.
pub const MOTION_NODES: &[&str] = &[
    "position",
    "velocity",
    "acceleration",
    "speed",
    "distance",
    "approach",
    "angular-velocity",
    "angular-speed",
    "forward",
    "up",
    "scale",
];

const USAGE: &str = "(motion shot \"car-pass.glb\")";

/// One `motion` form's file.
pub(crate) struct MotionFile {
    pub name: String,
    pub span: Span,
    pub shot: Arc<Shot>,
    /// Scene time at the file's time 0.
    pub start: f64,
    /// The form as the printer writes it (the file by its resolved path).
    pub form: String,
}

/// A glTF node of one of the scene's motion files.
pub(crate) struct NodeRef {
    pub shot: Arc<Shot>,
    pub node: NodeIndex,
    pub start: f64,
    pub name: String,
}

impl NodeRef {
    /// One of the node's tracks (`Shot::position`, `Shot::forward` …) on the scene's
    /// timeline.
    fn track(&self, of: fn(&Shot, NodeIndex) -> Arc<dyn Trajectory>) -> Arc<dyn Trajectory> {
        let trajectory = of(&self.shot, self.node);
        if self.start == 0.0 {
            trajectory
        } else {
            Arc::new(Shifted(trajectory, self.start))
        }
    }

    pub fn position(&self) -> Arc<dyn Trajectory> {
        self.track(Shot::position)
    }

    pub fn forward(&self) -> Arc<dyn Trajectory> {
        self.track(Shot::forward)
    }
}

impl Lowerer<'_> {
    /// `(motion NAME "file.glb" :animation "name" :start s)`.
    pub(crate) fn read_motion(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let name_expr = items.get(1).filter(|e| e.as_symbol().is_some());
        let path_expr = items.get(2).and_then(|e| match &e.kind {
            ExprKind::Str(path) => Some((e, path)),
            _ => None,
        });
        let (Some(name_expr), Some((path_expr, path))) = (name_expr, path_expr) else {
            return Err(self
                .diag(
                    "timbre::bad-motion",
                    "`motion` needs a name and a glTF file",
                    origin,
                )
                .label(form.span, "incomplete")
                .help(format!("write {USAGE}")));
        };
        let name = name_expr.as_symbol().unwrap_or_default().to_owned();
        if let Some(first) = self.names.motions.iter().find(|m| m.name == name) {
            return Err(self
                .diag(
                    "timbre::duplicate-motion",
                    format!("motion `{name}` is defined twice"),
                    origin,
                )
                .label(name_expr.span, "again")
                .label(first.span, "first")
                .help("give each motion file its own name"));
        }
        let options = self.options(&items[3..], "motion", &["animation", "start"], origin)?;
        let animation = match options.get("animation") {
            Some(e) => match &e.kind {
                ExprKind::Str(s) => Some(s.clone()),
                _ => {
                    return Err(self
                        .diag(
                            "timbre::bad-motion",
                            "`:animation` names one of the file's animations",
                            origin,
                        )
                        .label(e.span, "expected a name in quotes")
                        .help("write :animation \"Action\""))
                }
            },
            None => None,
        };
        let start = match options.get("start") {
            Some(e) => self.constant_option(e, "the start", origin)?,
            None => 0.0,
        };
        let (resolved, bytes) = self
            .options
            .loader
            .load(path, origin.dir.as_deref())
            .map_err(|e| {
                self.diag(
                    "timbre::motion-unreadable",
                    format!("cannot read `{path}`: {e}"),
                    origin,
                )
                .label(path_expr.span, "this file")
                .help("give the path of a .glb or .gltf file, relative to this file")
            })?;
        let shot = self
            .read_shot(&bytes, &resolved, &ShotOptions { animation })
            .map_err(|e| e.diag(path_expr.span).in_source(&origin.source))?;
        let form = motion_form(&name, &resolved, options.get("animation"), start);
        self.names.motions.push(MotionFile {
            name,
            span: name_expr.span,
            shot: Arc::new(shot),
            start,
            form,
        });
        Ok(())
    }

    /// The glTF file `bytes`, read from `resolved`: its external buffers through the
    /// host's loader, relative to it.
    pub(crate) fn read_shot(
        &self,
        bytes: &[u8],
        resolved: &std::path::Path,
        options: &ShotOptions,
    ) -> Result<Shot, timbre_motion::MotionError> {
        let dir = resolved.parent().map(|d| d.to_path_buf());
        let loader = self.options.loader;
        let mut resource = |uri: &str| {
            loader
                .load(uri, dir.as_deref())
                .map(|(_, bytes)| bytes)
                .map_err(|e| e.to_string())
        };
        Shot::read(bytes, &mut resource, options)
    }

    /// A scene with motion files and no `:duration` lasts as long as its motion: to
    /// the last key of its files (each from its `:start`), the length of the shot.
    pub(crate) fn default_motion_duration(&mut self) {
        if self.settings.duration.is_some() {
            return;
        }
        let end = self
            .names
            .motions
            .iter()
            .map(|m| m.start + m.shot.duration())
            .fold(f64::NEG_INFINITY, f64::max);
        if end > 0.0 {
            self.settings.duration = Some(end);
        }
    }

    /// The node named by a string, in whichever motion file has it.
    pub(crate) fn motion_node(&self, name_expr: &Expr, origin: &Origin) -> Result<NodeRef, Diag> {
        let ExprKind::Str(name) = &name_expr.kind else {
            return Err(self
                .diag(
                    "timbre::bad-motion-node",
                    format!(
                        "expected a node's name in quotes, found {}",
                        name_expr.describe()
                    ),
                    origin,
                )
                .label(name_expr.span, "not a name")
                .help("write the glTF node's name in quotes, as in (position \"Ball\")"));
        };
        let found: Vec<(&MotionFile, NodeIndex)> = self
            .names
            .motions
            .iter()
            .filter_map(|m| Some((m, m.shot.node(name)?)))
            .collect();
        match found.as_slice() {
            [(file, node)] => Ok(NodeRef {
                shot: file.shot.clone(),
                node: *node,
                start: file.start,
                name: name.clone(),
            }),
            [] if self.names.incomplete || self.names.motion_failed => {
                Err(self.follow_on(name, name_expr.span, origin))
            }
            [] if self.names.motions.is_empty() => Err(self
                .diag(
                    "timbre::unknown-node",
                    format!("no motion file to find node `{name}` in"),
                    origin,
                )
                .label(name_expr.span, "which file?")
                .help(format!("read an animated glTF file first: {USAGE}"))),
            [] => {
                let names = self.names.motions.iter().flat_map(|m| m.shot.node_names());
                let help = match super::did_you_mean(name, names) {
                    Some(close) => format!("did you mean \"{close}\"?"),
                    None => {
                        let all: Vec<String> = self
                            .names
                            .motions
                            .iter()
                            .flat_map(|m| m.shot.node_names())
                            .take(12)
                            .map(|n| format!("\"{n}\""))
                            .collect();
                        format!("the nodes are {}", all.join(", "))
                    }
                };
                Err(self
                    .diag(
                        "timbre::unknown-node",
                        format!("no node is named \"{name}\""),
                        origin,
                    )
                    .label(name_expr.span, "not in the motion files")
                    .help(help))
            }
            [(first, _), (second, _), ..] => Err(self
                .diag(
                    "timbre::ambiguous-node",
                    format!(
                        "node \"{name}\" is in both `{}` and `{}`",
                        first.name, second.name
                    ),
                    origin,
                )
                .label(name_expr.span, "which one?")
                .help("rename the node in one of the files")),
        }
    }

    /// A track: a node's name (its position), a keyframed vector variable, or
    /// `(position X)`, `(forward "N")`, `(up "N")`, `(angular-velocity "N")`.
    pub(crate) fn trajectory(
        &mut self,
        e: &Expr,
        origin: &Origin,
    ) -> Result<Arc<dyn Trajectory>, Diag> {
        let wrong = |l: &Self| {
            l.diag(
                "timbre::not-a-track",
                format!("expected a track, found {}", e.describe()),
                origin,
            )
            .label(e.span, "not a track")
            .help("give a node's name in quotes (\"Ball\"), a keyframed vector, or (position …) of one")
        };
        match &e.kind {
            ExprKind::Str(_) => Ok(self.motion_node(e, origin)?.position()),
            ExprKind::Symbol(name) => match self.names.vector_keyframes.get(name.as_str()) {
                Some(tracks) if tracks.len() == 3 => Ok(Arc::new(KeyedTrajectory(Arc::new([
                    tracks[0].clone(),
                    tracks[1].clone(),
                    tracks[2].clone(),
                ])))),
                Some(tracks) => Err(self
                    .diag(
                        "timbre::not-a-track",
                        format!("`{name}` has {} coordinates, not 3", tracks.len()),
                        origin,
                    )
                    .label(e.span, "not a position")
                    .help("a track of motion is keyed as (time (x y z)) triples")),
                None if self.names.failed.contains(name.as_str()) => {
                    Err(self.follow_on(name, e.span, origin))
                }
                None => Err(wrong(self)),
            },
            ExprKind::List(items) => {
                let head = items.first().and_then(Expr::as_symbol);
                let [_, arg] = items.as_slice() else {
                    return Err(wrong(self));
                };
                match head {
                    Some("position") => self.trajectory(arg, origin),
                    Some("forward") => Ok(self.motion_node(arg, origin)?.forward()),
                    Some("up") => {
                        let node = self.motion_node(arg, origin)?;
                        Ok(node.track(Shot::up))
                    }
                    Some("angular-velocity") => {
                        let node = self.motion_node(arg, origin)?;
                        Ok(node.track(Shot::angular_velocity))
                    }
                    _ => Err(wrong(self)),
                }
            }
            _ => Err(wrong(self)),
        }
    }

    /// A call of one of [`MOTION_NODES`]: its tracks, then `:time T` to read it at
    /// scene time T instead of now.
    pub(crate) fn lower_motion_node(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let (tracks, time_expr) = match call.args {
            [tracks @ .., key, value] if matches!(&key.kind, ExprKind::Keyword(k) if k == "time") => {
                (tracks, Some(value))
            }
            all => (all, None),
        };
        let (arity, usage) = match call.name {
            "distance" | "approach" => (2, format!("({} \"Car\" \"Camera\")", call.name)),
            _ => (1, format!("({} \"Ball\")", call.name)),
        };
        if tracks.len() != arity {
            return Err(self
                .diag(
                    "timbre::arity",
                    format!(
                        "`{}` takes {arity} track{}, found {} argument{}",
                        call.name,
                        super::plural(arity),
                        tracks.len(),
                        super::plural(tracks.len())
                    ),
                    origin,
                )
                .label(call.span, "here")
                .help(format!(
                    "write {usage}, and :time T to read it at scene time T"
                )));
        }
        let (trajectory, quantity) = match call.name {
            "position" => (self.trajectory(&tracks[0], origin)?, Quantity::Position),
            "velocity" => (self.trajectory(&tracks[0], origin)?, Quantity::Velocity),
            "acceleration" => (self.trajectory(&tracks[0], origin)?, Quantity::Acceleration),
            "speed" => (self.trajectory(&tracks[0], origin)?, Quantity::Speed),
            "distance" | "approach" => {
                let a = self.trajectory(&tracks[0], origin)?;
                let b = self.trajectory(&tracks[1], origin)?;
                let quantity = if call.name == "distance" {
                    Quantity::Length
                } else {
                    Quantity::Approach
                };
                (Arc::new(Difference(a, b)) as Arc<dyn Trajectory>, quantity)
            }
            "angular-speed" => {
                let node = self.motion_node(&tracks[0], origin)?;
                let omega = node.track(Shot::angular_velocity);
                (omega, Quantity::Length)
            }
            "scale" => {
                let node = self.motion_node(&tracks[0], origin)?;
                (node.track(Shot::scale), Quantity::Position)
            }
            // forward, up, angular-velocity: the vector itself.
            _ => {
                let whole = Expr {
                    kind: ExprKind::List(
                        std::iter::once(Expr {
                            kind: ExprKind::Symbol(call.name.into()),
                            span: call.span,
                        })
                        .chain(tracks.iter().cloned())
                        .collect(),
                    ),
                    span: call.span,
                };
                (self.trajectory(&whole, origin)?, Quantity::Position)
            }
        };
        let time = match time_expr {
            Some(e) => {
                let node = self.lower(e, origin, scope)?;
                let arg = Arg {
                    node,
                    span: e.span,
                    given: true,
                };
                self.check_one_lane(&arg, "the time motion is read at", origin)?;
                node
            }
            None => self.scene_time_node(),
        };
        let kernel = MotionKernel {
            name: motion_node_name(call.name),
            trajectory,
            quantity,
            written: Some(self.written_motion(call.name, tracks)),
        };
        Ok(self.graph.add(Op::Stateful(Arc::new(kernel)), vec![time]))
    }

    /// How a motion node was written, for the printer: the call with its tracks, and
    /// the `motion` and `keyframes` forms they name.
    fn written_motion(&self, name: &str, tracks: &[Expr]) -> Written {
        let mut forms = vec![];
        let mut stack: Vec<&Expr> = tracks.iter().collect();
        while let Some(e) = stack.pop() {
            match &e.kind {
                ExprKind::Str(node) => {
                    if let Some(file) = self
                        .names
                        .motions
                        .iter()
                        .find(|m| m.shot.node(node).is_some())
                    {
                        forms.push(file.form.clone());
                    }
                }
                ExprKind::Symbol(variable) => {
                    if let Some(tracks) = self.names.vector_keyframes.get(variable.as_str()) {
                        forms.push(crate::print::vector_keyframes_text(variable, tracks));
                    }
                }
                ExprKind::List(items) => stack.extend(items),
                _ => {}
            }
        }
        forms.dedup();
        let call = std::iter::once(name.to_owned())
            .chain(tracks.iter().map(|e| {
                timbre_syntax::print(std::slice::from_ref(e))
                    .trim_end()
                    .to_owned()
            }))
            .collect::<Vec<_>>()
            .join(" ");
        Written {
            call: format!("({call})"),
            forms,
        }
    }

    /// `t` plus the scene time at the instance's start: what keyframes and motion
    /// read.
    pub(crate) fn scene_time_node(&mut self) -> NodeId {
        let t = self.graph.add(Op::Time, vec![]);
        let offset = self.graph.constant(self.time_offset);
        self.graph.add(Op::Binary(BinaryOp::Add), vec![t, offset])
    }
}

/// `(motion NAME "PATH" :animation "A" :start S)` as text, the path resolved so that
/// the printed form reads the same file from anywhere.
fn motion_form(name: &str, path: &std::path::Path, animation: Option<&Expr>, start: f64) -> String {
    let mut items = vec![
        name.to_owned(),
        timbre_syntax::print(&[Expr {
            kind: ExprKind::Str(path.display().to_string()),
            span: Span::default(),
        }])
        .trim_end()
        .to_owned(),
    ];
    if let Some(animation) = animation {
        items.push(format!(
            ":animation {}",
            timbre_syntax::print(std::slice::from_ref(animation)).trim_end()
        ));
    }
    if start != 0.0 {
        items.push(format!(":start {start:?}"));
    }
    format!("(motion {})", items.join(" "))
}

/// The `'static` name of a motion node (the kernel's name in pictures and dumps).
fn motion_node_name(name: &str) -> &'static str {
    MOTION_NODES
        .iter()
        .find(|n| **n == name)
        .copied()
        .unwrap_or("motion")
}
