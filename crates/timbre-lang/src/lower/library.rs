//! A library of sound classes kept after lowering, for hosts that instantiate classes
//! from code: the paper's functional interface. Each instantiation lowers the class
//! body afresh with its parameters bound to the host's values (constants, keyframe
//! tracks, or variables the host sets while rendering) under a timer node.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use super::space::DeclaredSpace;
use super::{
    CompileOptions, Definition, Lowerer, Origin, Scope, Settings, DECLICK_IN, DECLICK_OUT,
};
use timbre_diag::{Diag, Diagnostics, SourceFile};
use timbre_ir::keyframes::KeyframeTrack;
use timbre_ir::op::{FadeIn, Op};
use timbre_ir::Variable;
use timbre_ir::{Graph, NodeId};

/// What a class parameter is bound to.
#[derive(Clone, Debug)]
pub enum ParamValue {
    Constant(f64),
    /// A track read on the scene's timeline (at the instance's t plus its start).
    Keyframes(Arc<KeyframeTrack>),
    Variable(Variable),
}

impl From<f64> for ParamValue {
    fn from(x: f64) -> Self {
        ParamValue::Constant(x)
    }
}

/// Sound classes (and other definitions and keyframes) read from text.
#[derive(Clone, Debug)]
pub struct Library {
    definitions: HashMap<String, Definition>,
    keyframes: HashMap<String, Arc<KeyframeTrack>>,
    settings: Settings,
    classes: Vec<String>,
    /// The forms of space it declares, read as a scene file's.
    space: Option<DeclaredSpace>,
}

/// One instantiated class: its tree (timer at the root) and where it starts.
#[derive(Clone, Debug)]
pub struct Instantiated {
    pub graph: Graph,
    pub root: NodeId,
}

impl Library {
    /// Reads a library: definitions, `define-sound` classes, keyframes, includes. A
    /// sound or an instance in it is an error (a library only defines).
    pub fn compile(
        source: Arc<SourceFile>,
        base_dir: Option<&Path>,
        options: &CompileOptions<'_>,
    ) -> Result<Library, Diagnostics> {
        let mut lowerer = Lowerer::new(options);
        lowerer.read_file(source, base_dir.map(Path::to_path_buf), None);
        for (form, origin) in lowerer.sounds.iter().chain(&lowerer.scene.instance_forms) {
            let diag = Diag::new(
                "timbre::library-not-definitions",
                "a library of sound classes may hold only definitions and the forms of space",
            )
            .label(form.span, "not a definition")
            .help("remove it, or render the file as a scene; a host starts instances")
            .in_source(&origin.source);
            lowerer.errors.push(diag);
        }
        // Every class is checked now, not at its first instance.
        lowerer.check_unused_definitions(true);
        let space = lowerer.read_library_space();
        if let Some(errors) = lowerer.take_errors() {
            return Err(errors);
        }
        let classes = lowerer
            .names
            .order
            .iter()
            .filter(|n| lowerer.names.definitions.get(*n).is_some_and(|d| d.class))
            .cloned()
            .collect();
        Ok(Library {
            definitions: lowerer.names.definitions,
            keyframes: lowerer.names.keyframes,
            settings: lowerer.settings,
            classes,
            space,
        })
    }

    /// The listener, microphones, sources, room and obstacles the library declares
    /// (`None` if it declares none), for a host to place and move instances in.
    pub fn space(&self) -> Option<&DeclaredSpace> {
        self.space.as_ref()
    }

    /// The sound classes and their parameter names, in definition order.
    pub fn classes(&self) -> impl Iterator<Item = (&str, Vec<&str>)> {
        self.classes.iter().map(|name| {
            let params = self.definitions[name]
                .params
                .iter()
                .map(|(p, _)| p.as_str())
                .collect();
            (name.as_str(), params)
        })
    }

    /// The keyframed variables the library defines.
    pub fn keyframes(&self, name: &str) -> Option<&Arc<KeyframeTrack>> {
        self.keyframes.get(name)
    }

    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Instantiates `class` with every parameter bound, starting at scene time
    /// `start` and, if given, stopping at `stop` (with the scene's declick ramps: at
    /// the start only if the sound does not start at zero).
    pub fn instantiate(
        &self,
        class: &str,
        params: &[(&str, ParamValue)],
        start: f64,
        stop: Option<f64>,
        options: &CompileOptions<'_>,
    ) -> Result<Instantiated, Diagnostics> {
        let fade_in = FadeIn::IfNotZero(DECLICK_IN);
        self.instantiate_with_fade_in(class, params, start, stop, fade_in, options)
    }

    /// [`Library::instantiate`] with the fade-in `fade_in` (an instance's `:declick`).
    pub fn instantiate_with_fade_in(
        &self,
        class: &str,
        params: &[(&str, ParamValue)],
        start: f64,
        stop: Option<f64>,
        fade_in: FadeIn,
        options: &CompileOptions<'_>,
    ) -> Result<Instantiated, Diagnostics> {
        let def = match self.definitions.get(class) {
            Some(def) if def.class => def,
            _ => {
                let help = match super::did_you_mean(class, self.classes.iter().map(String::as_str))
                {
                    Some(close) => format!("did you mean `{close}`?"),
                    None => format!("the classes are: {}", self.classes.join(", ")),
                };
                return Err(Diagnostics::one(
                    Diag::new(
                        "timbre::unknown-class",
                        format!("unknown sound class `{class}`"),
                    )
                    .help(help),
                ));
            }
        };
        let names: Vec<&str> = def.params.iter().map(|(p, _)| p.as_str()).collect();
        let list = names
            .iter()
            .map(|p| format!(":{p}"))
            .collect::<Vec<_>>()
            .join(" ");
        for (given, _) in params {
            if !names.contains(given) {
                return Err(Diagnostics::one(
                    Diag::new(
                        "timbre::unknown-keyword",
                        format!("`{class}` has no parameter `{given}`"),
                    )
                    .help(format!("its parameters are {list}")),
                ));
            }
        }
        if let Some(missing) = names.iter().find(|n| !params.iter().any(|(g, _)| g == *n)) {
            return Err(Diagnostics::one(
                Diag::new(
                    "timbre::arity",
                    format!("`{class}` needs a value for `{missing}`"),
                )
                .help(format!("its parameters are {list}")),
            ));
        }
        if stop.is_some_and(|stop| stop <= start) || start < 0.0 {
            return Err(Diagnostics::one(
                Diag::new(
                    "timbre::stop-before-start",
                    format!("`{class}` would start at {start} s and stop at {stop:?} s"),
                )
                .help("start at a time ≥ 0, and stop after the start"),
            ));
        }
        let mut lowerer = Lowerer::new(options);
        lowerer.names.definitions = self.definitions.clone();
        lowerer.names.keyframes = self.keyframes.clone();
        lowerer.settings = self.settings.clone();
        if let Some(seed) = options.seed {
            lowerer.settings.seed = seed;
        }
        lowerer.time_offset = start;
        let mut scope = Scope::new();
        for name in &names {
            let value = &params
                .iter()
                .find(|(g, _)| g == name)
                .expect("checked above")
                .1;
            let node = match value {
                ParamValue::Constant(x) => lowerer.graph.constant(*x),
                ParamValue::Keyframes(track) => lowerer.keyframe_node(track.clone()),
                ParamValue::Variable(v) => {
                    let read = lowerer.graph.add(Op::Variable(v.named(name)), vec![]);
                    if v.lag() > 0.0 {
                        let seconds = lowerer.graph.constant(v.lag());
                        lowerer.stateful(timbre_ir::dsp::control::Lag, vec![read, seconds])
                    } else {
                        read
                    }
                }
            };
            scope.push((name.to_string(), node));
        }
        let origin = Origin {
            source: def.source.clone(),
            dir: def.dir.clone(),
        };
        lowerer.expansion.expanding.push(class.to_owned());
        let sound = lowerer
            .lower(&def.body, &origin, &mut scope)
            .map_err(Diagnostics::one)?;
        let t = lowerer.graph.add(Op::Time, vec![]);
        let root = lowerer.graph.add(
            Op::Timer {
                length: stop.map(|stop| stop - start),
                fade_in,
                fade_out: DECLICK_OUT,
            },
            vec![sound, t],
        );
        if lowerer.graph.width(root) != 1 {
            return Err(Diagnostics::one(
                Diag::new(
                    "timbre::wide-sound",
                    format!(
                        "class `{class}` is {} lanes wide",
                        lowerer.graph.width(root)
                    ),
                )
                .help("a sound class is one lane: sum its lanes with (combine …)"),
            ));
        }
        Ok(Instantiated {
            graph: lowerer.graph,
            root,
        })
    }
}

impl Lowerer<'_> {
    /// Reads a library's forms of space (after its definitions, as a scene file's),
    /// pushing their errors; the space they declare, if any.
    fn read_library_space(&mut self) -> Option<DeclaredSpace> {
        let forms = std::mem::take(&mut self.scene.space_forms);
        let origin = forms.last()?.1.clone();
        // A library has no scene form: its listener is checked against the host's
        // channels (a pair, two ears, an Ambisonic order, a layout).
        if self.settings.channels.is_none() {
            self.settings.channels = self.options.channels;
        }
        let mut failed = false;
        for (form, origin) in &forms {
            if let Err(diag) = self.read_space_form(form, origin) {
                self.errors.push(diag);
                failed = true;
            }
        }
        if failed {
            return None;
        }
        match self.declared_space(&origin) {
            Ok(space) => space,
            Err(diag) => {
                self.errors.push(diag);
                None
            }
        }
    }
}
