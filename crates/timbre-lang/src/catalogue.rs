//! The node catalogue: every built-in node, declared once.
//!
//! An entry gives the node's name, its parameters (with defaults, which are also
//! its keyword names), whether it takes `:seed`, its width rule, whether it is pure
//! or stateful, the `lang-spec/nodes.md` section that defines it, and how it is
//! built. Everything that lists nodes derives from [`NODES`]: lowering, "did you
//! mean", reserved names, the REPL's completion, the fuzzer's arities, and the tidy
//! tests that hold every entry to a spec section, a conformance case and a place in
//! the random-tree generator.
//!
//! A pure element-wise node is a formula in [`timbre_ir::op`] plus an entry here; a
//! stateful node is a [`timbre_ir::kernel::StatefulKernel`] in its own file plus an
//! entry here. See "Adding a built-in node" in `docs/architecture.md`.

use std::sync::Arc;

use crate::lower::{Bound, Call, Lowerer, Origin, Scope, MAX_BUFFER_SECONDS, MAX_LANES};
use timbre_diag::Diag;
use timbre_ir::dsp::blep::{BandLimited, Wave};
use timbre_ir::dsp::control::{Lag, Latch};
use timbre_ir::dsp::delay::{Allpass, Comb, Delay};
use timbre_ir::dsp::envelope::AdsrEnvelope;
use timbre_ir::dsp::expressive::{
    locked_weights, Energetic, InverseImportance, LockError, Sputter, SweepCurve,
};
use timbre_ir::dsp::filter::{Biquad, BiquadKind, OnePoleLowpass, Resonator, Resonz};
use timbre_ir::dsp::noise::{hash2, lane_seeds, MarkovNoise, PinkNoise};
use timbre_ir::dsp::tube::ALUMINIUM;
use timbre_ir::op::{BinaryOp, Op, TernaryOp, UnaryOp};
use timbre_ir::NodeId;

pub use crate::lower::{FORMS, MOTION_NODES};

pub(crate) mod physical;

/// One parameter of a node: its keyword name and its default, if it has one.
#[derive(Clone, Copy, Debug)]
pub struct Param<'n> {
    pub name: &'n str,
    pub default: Option<f64>,
}

/// A required parameter.
pub const fn p(name: &'static str) -> Param<'static> {
    Param {
        name,
        default: None,
    }
}

/// An optional parameter with its default.
pub const fn opt(name: &'static str, default: f64) -> Param<'static> {
    Param {
        name,
        default: Some(default),
    }
}

/// What evaluating the node involves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A function of its arguments at the same sample (folded when they are constant).
    Pure,
    /// Keeps state from sample to sample.
    Stateful,
    /// Computed while lowering: its value is a constant.
    Constant,
}

/// How the output width follows from the arguments'.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Width {
    /// Arguments are one lane or all one width W (checked while lowering); the
    /// output is W lanes.
    Broadcast,
    /// The node's builder checks its arguments itself (see its section in nodes.md).
    Own,
}

/// How lowering makes the node from its bound arguments.
#[derive(Clone, Copy)]
pub(crate) enum Build {
    Unary(UnaryOp),
    Binary(BinaryOp),
    Ternary(TernaryOp),
    /// A left fold of a binary operation over one or more arguments.
    Fold(BinaryOp),
    /// Anything else, from arguments bound to the parameters.
    Args(fn(&mut Lowerer<'_>, &Bound<'_>) -> Result<NodeId, Diag>),
    /// A node that binds its own arguments (a file name first, or `:material`).
    Form(fn(&mut Lowerer<'_>, &Call<'_>, &Origin, &mut Scope) -> Result<NodeId, Diag>),
}

/// One built-in node.
pub struct NodeSpec {
    pub name: &'static str,
    pub params: &'static [Param<'static>],
    /// The last parameter takes one or more arguments.
    pub variadic: bool,
    /// Takes `:seed K` for an independent copy.
    pub random: bool,
    pub kind: Kind,
    pub width: Width,
    /// The heading of the `lang-spec/nodes.md` section that defines it.
    pub section: &'static str,
    /// For differential tests: see the `exact` and `jumpy` marks of `NODES`.
    pub exact: bool,
    pub jumpy: bool,
    /// A one-lane tree that exercises the node (rendered under both engines by the
    /// differential tests); empty where that needs a file (`sample`).
    pub example: &'static str,
    pub(crate) build: Build,
}

impl NodeSpec {
    const fn new(
        name: &'static str,
        params: &'static [Param<'static>],
        section: &'static str,
        build: Build,
        example: &'static str,
    ) -> Self {
        NodeSpec {
            name,
            params,
            variadic: false,
            random: false,
            kind: Kind::Pure,
            width: Width::Broadcast,
            section,
            exact: false,
            jumpy: false,
            example,
            build,
        }
    }

    const fn variadic(mut self) -> Self {
        self.variadic = true;
        self
    }

    const fn random(mut self) -> Self {
        self.random = true;
        self
    }

    const fn stateful(mut self) -> Self {
        self.kind = Kind::Stateful;
        self
    }

    const fn constant(mut self) -> Self {
        self.kind = Kind::Constant;
        self
    }

    const fn own_width(mut self) -> Self {
        self.width = Width::Own;
        self
    }

    /// Arguments it takes at least, and at most (None: any number).
    pub fn arity(&self) -> (usize, Option<usize>) {
        let required = self.params.iter().filter(|p| p.default.is_none()).count();
        let max = (!self.variadic).then_some(self.params.len());
        (required, max)
    }
}

/// Marks a node exact: bit-identical in any IEEE engine without FMA if its arguments are.
const fn exact(mut spec: NodeSpec) -> NodeSpec {
    spec.exact = true;
    spec
}

/// Marks a node jumpy: discontinuous in every argument (or within a sample, as `saw-bl`).
const fn jumpy(mut spec: NodeSpec) -> NodeSpec {
    spec.jumpy = true;
    spec
}

/// The built-in node called `name`.
pub fn lookup(name: &str) -> Option<&'static NodeSpec> {
    NODES.iter().find(|n| n.name == name)
}

/// Every built-in node's name, in catalogue order.
pub fn names() -> impl Iterator<Item = &'static str> {
    NODES.iter().map(|n| n.name)
}

const MATHS: &str = "Arithmetic and maths";
const LOGIC: &str = "Comparisons and logic";
pub(crate) const WAVES: &str = "Waveforms";
pub(crate) const BAND_LIMITED: &str = "Band-limited waveforms";
const LEVELS: &str = "Levels and pitches";
const NOISES: &str = "Noises";
const VECTORS: &str = "Vector nodes";
const FILTERS: &str = "Filters";
const DELAYS: &str = "Delays";
const CONTROL: &str = "Control";
const ENVELOPES: &str = "Envelopes";
const EXPRESSIVE: &str = "Expressive nodes";
const PHYSICAL: &str = "Physical models";

const X: &[Param<'static>] = &[p("x")];
const AB: &[Param<'static>] = &[p("a"), p("b")];
const BIQUAD: &[Param<'static>] = &[p("x"), p("freq"), opt("q", std::f64::consts::FRAC_1_SQRT_2)];

/// Every built-in node. (`let` and the top-level forms are not nodes: see
/// `lower::forms`.) The last argument of each entry is an example: a one-lane
/// tree that exercises the node, which the differential tests render under both
/// engines.
pub static NODES: &[NodeSpec] = &[
    // Arithmetic and maths.
    exact(NodeSpec::new(
        "+",
        X,
        MATHS,
        Build::Fold(BinaryOp::Add),
        "(+ (sine (* t 440)) 0.25 (* 0.1 t))",
    ))
    .variadic(),
    exact(NodeSpec::new(
        "*",
        X,
        MATHS,
        Build::Fold(BinaryOp::Mul),
        "(* (sine (* t 440)) (sine (* t 3)) 0.5)",
    ))
    .variadic(),
    exact(NodeSpec::new(
        "-",
        X,
        MATHS,
        Build::Args(minus),
        "(- (- (sine (* t 440))) (* 0.1 t) 0.25)",
    ))
    .variadic(),
    NodeSpec::new(
        "/",
        X,
        MATHS,
        Build::Args(divide),
        "(/ (sine (* t 440)) (+ 2 t) (/ (+ 3 (sine t))))",
    )
    .variadic(),
    exact(NodeSpec::new(
        "min",
        X,
        MATHS,
        Build::Fold(BinaryOp::Min),
        "(min (sine (* t 440)) (sine (* t 330)) 0.5)",
    ))
    .variadic(),
    exact(NodeSpec::new(
        "max",
        X,
        MATHS,
        Build::Fold(BinaryOp::Max),
        "(max (sine (* t 440)) (sine (* t 330)) -0.5)",
    ))
    .variadic(),
    NodeSpec::new(
        "pow",
        &[p("base"), p("exponent")],
        MATHS,
        Build::Binary(BinaryOp::Pow),
        "(pow (+ 1.5 (sine (* t 440))) (+ 1 t))",
    ),
    exact(jumpy(NodeSpec::new(
        "mod",
        &[p("x"), p("divisor")],
        MATHS,
        Build::Binary(BinaryOp::Mod),
        "(mod (* t 440) (+ 1 (* 0.5 (sine t))))",
    ))),
    NodeSpec::new(
        "exp",
        X,
        MATHS,
        Build::Unary(UnaryOp::Exp),
        "(exp (sine (* t 440)))",
    ),
    NodeSpec::new(
        "log",
        X,
        MATHS,
        Build::Unary(UnaryOp::Log),
        "(log (+ 1.5 (sine (* t 440))))",
    ),
    NodeSpec::new(
        "sqrt",
        X,
        MATHS,
        Build::Unary(UnaryOp::Sqrt),
        "(sqrt (+ 1 (sine (* t 440))))",
    ),
    exact(NodeSpec::new(
        "abs",
        X,
        MATHS,
        Build::Unary(UnaryOp::Abs),
        "(abs (sine (* t 440.7)))",
    )),
    NodeSpec::new(
        "sin",
        X,
        MATHS,
        Build::Unary(UnaryOp::Sin),
        "(sin (* t 2765))",
    ),
    NodeSpec::new(
        "cos",
        X,
        MATHS,
        Build::Unary(UnaryOp::Cos),
        "(cos (* t 2765))",
    ),
    NodeSpec::new(
        "tan",
        X,
        MATHS,
        Build::Unary(UnaryOp::Tan),
        "(* 0.1 (tan (* t 7)))",
    ),
    NodeSpec::new(
        "tanh",
        X,
        MATHS,
        Build::Unary(UnaryOp::Tanh),
        "(tanh (* 4 (sine (* t 440))))",
    ),
    exact(jumpy(NodeSpec::new(
        "floor",
        X,
        MATHS,
        Build::Unary(UnaryOp::Floor),
        "(* 0.1 (floor (* 4 (sine (* t 440.7)))))",
    ))),
    exact(jumpy(NodeSpec::new(
        "frac",
        X,
        MATHS,
        Build::Unary(UnaryOp::Frac),
        "(frac (* t 440))",
    ))),
    exact(NodeSpec::new(
        "clamp",
        &[p("x"), p("lo"), p("hi")],
        MATHS,
        Build::Ternary(TernaryOp::Clamp),
        "(clamp (* 2 (sine (* t 440))) -0.5 (sine t))",
    )),
    // Comparisons and logic.
    exact(jumpy(NodeSpec::new(
        "<",
        AB,
        LOGIC,
        Build::Binary(BinaryOp::Lt),
        "(< (sine (* t 440.7)) (sine (* t 3)))",
    ))),
    exact(jumpy(NodeSpec::new(
        ">",
        AB,
        LOGIC,
        Build::Binary(BinaryOp::Gt),
        "(> (sine (* t 440.7)) (sine (* t 3)))",
    ))),
    exact(jumpy(NodeSpec::new(
        "<=",
        AB,
        LOGIC,
        Build::Binary(BinaryOp::Le),
        "(<= (sine (* t 440.7)) 0)",
    ))),
    exact(jumpy(NodeSpec::new(
        ">=",
        AB,
        LOGIC,
        Build::Binary(BinaryOp::Ge),
        "(>= (sine (* t 440.7)) 0)",
    ))),
    exact(jumpy(NodeSpec::new(
        "=",
        AB,
        LOGIC,
        Build::Binary(BinaryOp::Eq),
        "(= (floor (* t 10)) 3)",
    ))),
    exact(jumpy(NodeSpec::new(
        "!=",
        AB,
        LOGIC,
        Build::Binary(BinaryOp::Ne),
        "(!= (floor (* t 10)) 3)",
    ))),
    exact(jumpy(NodeSpec::new(
        "and",
        X,
        LOGIC,
        Build::Fold(BinaryOp::And),
        "(and (> (sine (* t 440.7)) 0) (> (sine (* t 3)) 0))",
    )))
    .variadic(),
    exact(jumpy(NodeSpec::new(
        "or",
        X,
        LOGIC,
        Build::Fold(BinaryOp::Or),
        "(or (> (sine (* t 440.7)) 0.5) (> (sine (* t 3)) 0.5))",
    )))
    .variadic(),
    exact(jumpy(NodeSpec::new(
        "not",
        X,
        LOGIC,
        Build::Unary(UnaryOp::Not),
        "(not (> (sine (* t 440.7)) 0))",
    ))),
    exact(NodeSpec::new(
        "if",
        &[p("condition"), p("then"), p("else")],
        LOGIC,
        Build::Ternary(TernaryOp::If),
        "(if (< (frac t) 0.5) (sine (* t 440.7)) (sine (* t 660)))",
    )),
    // Waveforms.
    NodeSpec::new(
        "sine",
        X,
        WAVES,
        Build::Unary(UnaryOp::Sine),
        "(sine (* t 440))",
    ),
    exact(jumpy(NodeSpec::new(
        "sawtooth",
        X,
        WAVES,
        Build::Unary(UnaryOp::Sawtooth),
        "(sawtooth (* t 440))",
    ))),
    exact(jumpy(NodeSpec::new(
        "square",
        X,
        WAVES,
        Build::Unary(UnaryOp::Square),
        "(square (* t 440))",
    ))),
    exact(NodeSpec::new(
        "triangle",
        X,
        WAVES,
        Build::Unary(UnaryOp::Triangle),
        "(triangle (* t 440))",
    )),
    exact(jumpy(NodeSpec::new(
        "pulse",
        &[p("x"), opt("width", 0.5)],
        WAVES,
        Build::Binary(BinaryOp::Pulse),
        "(pulse (* t 440) (+ 0.5 (* 0.4 (sine t))))",
    ))),
    NodeSpec::new(
        "damp",
        X,
        "`damp`",
        Build::Unary(UnaryOp::Damp),
        "(* (damp (* 3 t)) (sine (* t 440)))",
    ),
    jumpy(NodeSpec::new(
        "saw-bl",
        X,
        BAND_LIMITED,
        Build::Args(saw_bl),
        "(saw-bl (phasor (+ 440 (* 200 (sine (* t 5))))))",
    ))
    .stateful(),
    jumpy(NodeSpec::new(
        "square-bl",
        X,
        BAND_LIMITED,
        Build::Args(square_bl),
        "(square-bl (* t 1234.5))",
    ))
    .stateful(),
    NodeSpec::new(
        "triangle-bl",
        X,
        BAND_LIMITED,
        Build::Args(triangle_bl),
        "(triangle-bl (* t 3456.7))",
    )
    .stateful(),
    // Levels and pitches.
    NodeSpec::new(
        "dbamp",
        &[p("db")],
        LEVELS,
        Build::Unary(UnaryOp::DbAmp),
        "(* (dbamp (* -20 t)) (sine (* t 440)))",
    ),
    NodeSpec::new(
        "ampdb",
        &[p("amp")],
        LEVELS,
        Build::Unary(UnaryOp::AmpDb),
        "(* 0.01 (ampdb (+ 1.5 (sine (* t 440)))))",
    ),
    NodeSpec::new(
        "midihz",
        &[p("note")],
        LEVELS,
        Build::Unary(UnaryOp::MidiHz),
        "(sine (phasor (midihz (+ 60 (* 12 (sine t))))))",
    ),
    NodeSpec::new(
        "hzmidi",
        &[p("hz")],
        LEVELS,
        Build::Unary(UnaryOp::HzMidi),
        "(* 0.01 (hzmidi (+ 440 (* 200 (sine (* t 440))))))",
    ),
    // Noises.
    NodeSpec::new(
        "noise",
        &[p("x"), opt("lanes", 1.0)],
        NOISES,
        Build::Args(noise),
        "(* 0.5 (combine (noise (* t (vector 440 660)) :lanes 2)))",
    )
    .random(),
    NodeSpec::new(
        "white",
        &[opt("lanes", 1.0)],
        NOISES,
        Build::Args(white),
        "(white :seed 3)",
    )
    .random(),
    NodeSpec::new(
        "pink",
        &[opt("lanes", 1.0)],
        NOISES,
        Build::Args(pink),
        "(combine (* (pink :lanes 2) (vector 0.3 -0.3)))",
    )
    .random()
    .stateful(),
    NodeSpec::new(
        "markov",
        &[p("rate"), opt("lanes", 1.0)],
        NOISES,
        Build::Args(markov),
        "(combine (markov (+ 50 (* 40 (sine t))) :lanes 3))",
    )
    .random()
    .stateful(),
    // Vector nodes.
    exact(NodeSpec::new(
        "rvector",
        &[p("n"), p("lo"), p("hi")],
        VECTORS,
        Build::Args(rvector),
        "(* 0.1 (combine (sine (* t (rvector 8 200 2000)))))",
    ))
    .random()
    .own_width(),
    exact(NodeSpec::new(
        "iota",
        &[p("n")],
        VECTORS,
        Build::Args(iota),
        "(* 0.2 (combine (sine (* t 110 (+ 1 (iota 4))))))",
    ))
    .constant()
    .own_width(),
    exact(NodeSpec::new(
        "vector",
        X,
        VECTORS,
        Build::Args(vector),
        "(* 0.3 (combine (sine (* t (vector 440 (+ 550 t) 660)))))",
    ))
    .variadic()
    .own_width(),
    exact(NodeSpec::new(
        "combine",
        X,
        VECTORS,
        Build::Args(combine),
        "(* 0.1 (combine (sine (* t (rvector 5 100 900)))))",
    ))
    .own_width(),
    exact(NodeSpec::new(
        "lanes",
        X,
        VECTORS,
        Build::Args(lanes),
        "(sine (* t 100 (lanes (rvector 5 0 1))))",
    ))
    .constant()
    .own_width(),
    exact(NodeSpec::new(
        "index",
        &[p("x"), p("i")],
        VECTORS,
        Build::Args(index),
        "(index (sine (* t (vector 440 550 660))) (* 3 (frac t)))",
    ))
    .own_width(),
    // Phase.
    NodeSpec::new(
        "phasor",
        &[p("freq"), opt("phase", 0.0)],
        "`phasor`",
        Build::Args(phasor),
        "(sine (phasor (+ 440 (* 100 (sine (* t 3)))) 0.25))",
    )
    .stateful(),
    // Filters.
    NodeSpec::new(
        "lowpass",
        BIQUAD,
        FILTERS,
        Build::Args(lowpass),
        "(lowpass (white) (+ 1000 (* 500 (sine t))))",
    )
    .stateful(),
    NodeSpec::new(
        "highpass",
        BIQUAD,
        FILTERS,
        Build::Args(highpass),
        "(highpass (white) 2000 2)",
    )
    .stateful(),
    NodeSpec::new(
        "bandpass",
        &[p("x"), p("freq"), opt("q", 1.0)],
        FILTERS,
        Build::Args(bandpass),
        "(bandpass (white) 1000 :q 10)",
    )
    .stateful(),
    NodeSpec::new(
        "onepole",
        &[p("x"), p("freq")],
        FILTERS,
        Build::Args(onepole),
        "(onepole (white) 500)",
    )
    .stateful(),
    NodeSpec::new(
        "resonator",
        &[p("x"), p("freq"), p("bandwidth")],
        FILTERS,
        Build::Args(resonator),
        "(resonator (white) 880 20)",
    )
    .stateful(),
    NodeSpec::new(
        "resonz",
        &[p("x"), p("freq"), p("bandwidth")],
        FILTERS,
        Build::Args(resonz),
        "(resonz (white) 880 20)",
    )
    .stateful(),
    // Delays.
    NodeSpec::new(
        "delay",
        &[p("x"), p("time"), opt("max", 0.0)],
        DELAYS,
        Build::Args(delay),
        "(delay (sine (* t 440)) (+ 0.01 (* 0.005 (sine t))) 0.02)",
    )
    .stateful(),
    NodeSpec::new(
        "comb",
        &[
            p("x"),
            p("delay"),
            p("feedback"),
            opt("damp", 0.0),
            opt("max", 0.0),
        ],
        DELAYS,
        Build::Args(comb),
        "(comb (* (white) (< t 0.005)) (/ 1 220) 0.99 :damp 0.3)",
    )
    .stateful(),
    NodeSpec::new(
        "allpass",
        &[p("x"), p("delay"), p("gain"), opt("max", 0.0)],
        DELAYS,
        Build::Args(allpass),
        "(allpass (white) (+ 0.005 (* 0.002 (sine t))) 0.6 :max 0.01)",
    )
    .stateful(),
    // Convolution and sampled sound (their first or second argument is a file).
    NodeSpec::new(
        "conv",
        &[p("input"), p("response"), opt("length", 1.0)],
        "`conv`",
        Build::Form(|l, call, origin, scope| l.lower_conv(call, origin, scope)),
        "(conv (* (white) (< t 0.01)) (* (damp (* 30 t)) (sine (* t 700))) :length 0.2)",
    )
    .stateful()
    .own_width(),
    NodeSpec::new(
        "sample",
        &[
            p("file"),
            opt("rate", 1.0),
            opt("start", 0.0),
            opt("loop", 0.0),
        ],
        "`sample`",
        Build::Form(|l, call, origin, scope| l.lower_sample(call, origin, scope)),
        "",
    )
    .stateful()
    .own_width(),
    // Control.
    exact(NodeSpec::new(
        "latch",
        &[p("x"), p("trigger")],
        CONTROL,
        Build::Args(latch),
        "(sine (* t 100 (+ 2 (latch (white) (square (* t 8))))))",
    ))
    .stateful(),
    NodeSpec::new(
        "lag",
        &[p("x"), p("seconds")],
        CONTROL,
        Build::Args(lag),
        "(sine (phasor (* 100 (+ 2 (lag (floor (* t 8)) 0.02)))))",
    )
    .stateful(),
    // Envelopes.
    NodeSpec::new(
        "env",
        &[
            p("x"),
            p("attack"),
            p("decay"),
            opt("hold", 0.0),
            opt("attack-curve", 0.0),
            opt("decay-curve", 0.0),
        ],
        ENVELOPES,
        Build::Args(env),
        "(* (env t 0.01 0.5 :hold 0.1 :decay-curve -4) (sine (* t 440)))",
    ),
    jumpy(NodeSpec::new(
        "adsr",
        &[
            p("gate"),
            p("attack"),
            p("decay"),
            p("sustain"),
            p("release"),
            opt("exp-release", 0.0),
        ],
        ENVELOPES,
        Build::Args(adsr),
        "(* (adsr (< (frac (* 2 t)) 0.3) 0.01 0.1 0.5 0.2) (sine (* t 440)))",
    ))
    .stateful(),
    // Expressive nodes (the 2006 schematic paper's aesthetic effects).
    NodeSpec::new(
        "gain-db",
        &[p("db"), p("x")],
        EXPRESSIVE,
        Build::Args(gain_db),
        "(gain-db (* -20 t) (sine (* t 440)))",
    ),
    NodeSpec::new(
        "pan",
        &[p("position"), p("x")],
        EXPRESSIVE,
        Build::Args(pan),
        "(index (pan (sine (* t 0.5)) (sine (* t 440))) 0)",
    )
    .own_width(),
    NodeSpec::new(
        "importance",
        &[p("sounds"), p("weights")],
        EXPRESSIVE,
        Build::Args(importance),
        "(importance (sine (* t (vector 220 330 440))) (vector (+ 1 (sine t)) 0.5 (* 2 t)))",
    )
    .own_width(),
    NodeSpec::new(
        "importance-locked",
        &[p("n"), p("percent")],
        EXPRESSIVE,
        Build::Args(importance_locked),
        "(importance (sine (* t (vector 220 330 440 550))) (importance-locked 4 67 20 10))",
    )
    .variadic()
    .constant()
    .own_width(),
    NodeSpec::new(
        "inverse-importance",
        &[p("sounds"), p("weights"), p("switch"), opt("transition", 0.5)],
        EXPRESSIVE,
        Build::Args(inverse_importance),
        "(inverse-importance (sine (* t (vector 220 330 440))) (vector 6 3 1) (> t 0.3) :transition 0.2)",
    )
    .stateful()
    .own_width(),
    NodeSpec::new(
        "energetic",
        &[p("speed"), p("source")],
        EXPRESSIVE,
        Build::Args(energetic),
        "(energetic (+ 1 (* 0.5 (sine (* t 2)))) (* (sine (* t 220)) (lowpass (white) 800)))",
    )
    .stateful()
    .own_width(),
    NodeSpec::new(
        "sputter",
        &[p("from"), p("to"), p("duration"), opt("curve", 1.0)],
        EXPRESSIVE,
        Build::Args(sputter),
        "(* (sputter 12 1 4) (sine (* t 110)))",
    )
    .stateful()
    .own_width(),
    // Physical models (constants computed from physical quantities).
    NodeSpec::new(
        "tube-modes",
        &[
            p("n"),
            p("length"),
            p("outer"),
            p("inner"),
            opt("youngs", ALUMINIUM.youngs),
            opt("density", ALUMINIUM.density),
        ],
        PHYSICAL,
        Build::Form(physical::tube_modes_form),
        "(* 0.1 (combine (* (sine (* t (tube-modes 5 0.3 0.025 0.022))) (damp (* t 3)))))",
    )
    .constant()
    .own_width(),
    NodeSpec::new(
        "modal",
        &[],
        "`modal`",
        Build::Form(|l, call, origin, scope| l.lower_modal(call, origin, scope)),
        "(modal :material steel :box (0.08 0.02 0.02) :voxel 0.005 :modes 8 :strike (0.04 0 0.01))",
    )
    .own_width(),
    NodeSpec::new(
        "impact",
        physical::IMPACT_PARAMS,
        PHYSICAL,
        Build::Form(physical::impact_form),
        "(resonator (impact :a steel :b oak :radius 0.01 :mass 0.03 :speed 1) 2000 20)",
    )
    .stateful()
    .own_width(),
    NodeSpec::new(
        "scrape",
        physical::SCRAPE_PARAMS,
        PHYSICAL,
        Build::Args(physical::scrape),
        "(resonator (scrape (* 0.3 (min 1 (* 4 t))) 2 :period 0.002 :seed 1) 1200 30)",
    )
    .random()
    .stateful()
    .own_width(),
    NodeSpec::new(
        "roll",
        physical::ROLL_PARAMS,
        PHYSICAL,
        Build::Form(physical::roll_form),
        "(resonator (roll 0.5 5 :radius 0.02 :a steel :b oak :grain 0.001) 800 20)",
    )
    .random()
    .stateful()
    .own_width(),
];

// ------------------------------------------------------------------ builders
// Each receives its arguments bound and, for `Width::Broadcast`, width-checked.

fn minus(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let nodes = b.nodes();
    if let [x] = nodes[..] {
        return Ok(l.graph.add(Op::Unary(UnaryOp::Neg), vec![x]));
    }
    Ok(l.fold(BinaryOp::Sub, &nodes))
}

fn divide(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let nodes = b.nodes();
    if let [x] = nodes[..] {
        let one = l.graph.constant(1.0);
        return Ok(l.graph.add(Op::Binary(BinaryOp::Div), vec![one, x]));
    }
    Ok(l.fold(BinaryOp::Div, &nodes))
}

fn noise(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let x = b.args[0].node;
    let lanes = noise_lanes(l, b)?;
    // The seed hashes `x` alone, so `:lanes` leaves lane 0 as the one-lane noise.
    let seed = l.random_seed("noise", b, &[x]);
    let seeds = lane_seeds(seed, lanes);
    Ok(l.graph.add(Op::Noise { seeds }, vec![x]))
}

fn white(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let lanes = l.const_count(&b.args[0], "the number of lanes", b.origin)?;
    let seed = l.random_seed("white", b, &[]);
    Ok(l.graph.add(
        Op::White {
            seeds: lane_seeds(seed, lanes),
        },
        vec![],
    ))
}

fn pink(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let lanes = l.const_count(&b.args[0], "the number of lanes", b.origin)?;
    let seed = l.random_seed("pink", b, &[]);
    let seeds = lane_seeds(seed, lanes);
    Ok(l.stateful(PinkNoise { seeds }, vec![]))
}

fn markov(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let rate = b.args[0].node;
    let lanes = noise_lanes(l, b)?;
    let seed = l.random_seed("markov", b, &[rate]);
    let seeds = lane_seeds(seed, lanes);
    Ok(l.stateful(MarkovNoise { seeds }, vec![rate]))
}

/// The lanes of a noise of one argument and `:lanes`: as many as the argument has,
/// or as `:lanes` asks (each lane a noise of its own seed, see `dsp::noise::lane_seeds`).
fn noise_lanes(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<usize, Diag> {
    let (input, lanes_arg) = (&b.args[0], &b.args[1]);
    let lanes = l.const_count(lanes_arg, "the number of lanes", b.origin)?;
    let width = l.graph.width(input.node);
    if width != 1 && lanes != 1 && width != lanes {
        let name = b.call.name;
        return Err(l
            .diag(
                "timbre::width-mismatch",
                format!("`{name}` of {lanes} lanes with an argument of {width} lanes"),
                b.origin,
            )
            .label(input.span, format!("{width} lanes"))
            .label(lanes_arg.span, format!("{lanes} lanes"))
            .help("give `:lanes` the argument's width, or leave it out: a wide argument already gives each lane its own noise"));
    }
    Ok(width.max(lanes))
}

fn rvector(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let all = &b.args;
    let n = l.const_count(&all[0], "the number of lanes", b.origin)?;
    let bounds_width = l.check_widths(b.call, &all[1..], b.origin)?;
    if bounds_width != 1 && bounds_width != n {
        let wide = all[1..]
            .iter()
            .find(|a| l.graph.width(a.node) != 1)
            .unwrap_or(&all[1]);
        return Err(l
            .diag(
                "timbre::width-mismatch",
                format!("`rvector` of {n} lanes with bounds of {bounds_width} lanes"),
                b.origin,
            )
            .label(wide.span, format!("{bounds_width} lanes"))
            .label(all[0].span, format!("{n} lanes"))
            .help("the bounds must be one lane, or one per lane of the vector"));
    }
    let seed = l.random_seed("rvector", b, &b.nodes());
    let unit: Vec<f64> = (0..n as u64)
        .map(|i| (hash2(seed, i) >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
        .collect();
    // lo + (hi − lo)·u: folds to a constant vector when lo and hi are constants.
    let unit = l.graph.const_vector(unit);
    let (lo, hi) = (all[1].node, all[2].node);
    let range = l.graph.add(Op::Binary(BinaryOp::Sub), vec![hi, lo]);
    let scaled = l.graph.add(Op::Binary(BinaryOp::Mul), vec![range, unit]);
    Ok(l.graph.add(Op::Binary(BinaryOp::Add), vec![lo, scaled]))
}

fn iota(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let n = l.const_count(&b.args[0], "the number of lanes", b.origin)?;
    Ok(l.graph.const_vector((0..n).map(|i| i as f64).collect()))
}

fn vector(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let nodes = b.nodes();
    let total: usize = nodes.iter().map(|n| l.graph.width(*n)).sum();
    if total > MAX_LANES {
        return Err(l.too_wide(b.call.span, total, b.origin));
    }
    Ok(l.graph.add(Op::Concat, nodes))
}

fn combine(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.graph.add(Op::Combine, b.nodes()))
}

fn lanes(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let w = l.graph.width(b.args[0].node);
    Ok(l.graph.constant(w as f64))
}

fn index(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    l.check_one_lane(&b.args[1], "the lane index", b.origin)?;
    Ok(l.graph.add(Op::Index, b.nodes()))
}

fn phasor(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.graph.add(Op::Phasor, b.nodes()))
}

fn env(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.graph.add(Op::Env, b.nodes()))
}

fn lowpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let kind = BiquadKind::Lowpass;
    Ok(l.stateful(Biquad { kind }, b.nodes()))
}

fn highpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let kind = BiquadKind::Highpass;
    Ok(l.stateful(Biquad { kind }, b.nodes()))
}

fn bandpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let kind = BiquadKind::Bandpass;
    Ok(l.stateful(Biquad { kind }, b.nodes()))
}

fn onepole(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(OnePoleLowpass, b.nodes()))
}

fn resonator(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(Resonator, b.nodes()))
}

fn resonz(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(Resonz, b.nodes()))
}

fn adsr(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(AdsrEnvelope, b.nodes()))
}

fn latch(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(Latch, b.nodes()))
}

fn lag(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(Lag, b.nodes()))
}

fn saw_bl(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(BandLimited { wave: Wave::Saw }, b.nodes()))
}

fn square_bl(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(BandLimited { wave: Wave::Square }, b.nodes()))
}

fn triangle_bl(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let wave = Wave::Triangle;
    Ok(l.stateful(BandLimited { wave }, b.nodes()))
}

fn delay(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let max_seconds = max_delay(l, b, 1, 2)?;
    Ok(l.stateful(Delay { max_seconds }, b.nodes()[..2].to_vec()))
}

fn comb(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let max_seconds = max_delay(l, b, 1, 4)?;
    Ok(l.stateful(Comb { max_seconds }, b.nodes()[..4].to_vec()))
}

fn allpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let max_seconds = max_delay(l, b, 1, 3)?;
    Ok(l.stateful(Allpass { max_seconds }, b.nodes()[..3].to_vec()))
}

fn gain_db(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let [db, x] = b.nodes()[..] else {
        unreachable!("two parameters")
    };
    let gain = l.graph.add(Op::Unary(UnaryOp::DbAmp), vec![db]);
    Ok(l.graph.add(Op::Binary(BinaryOp::Mul), vec![gain, x]))
}

/// Equal power: left x·cos θ, right x·sin θ, θ = (clamp(p, −1, 1) + 1)·π/4.
fn pan(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    l.check_one_lane(&b.args[0], "the pan position", b.origin)?;
    l.check_one_lane(&b.args[1], "the panned sound", b.origin)?;
    let [position, x] = b.nodes()[..] else {
        unreachable!("two parameters")
    };
    Ok(l.pan(x, position))
}

/// Sounds and weights of the importance nodes: one lane each, or N lanes each.
fn check_sounds_and_weights(l: &Lowerer<'_>, b: &Bound<'_>) -> Result<usize, Diag> {
    let (sounds, weights) = (&b.args[0], &b.args[1]);
    let (n, w) = (l.graph.width(sounds.node), l.graph.width(weights.node));
    if n == w {
        return Ok(n);
    }
    Err(l
        .diag(
            "timbre::width-mismatch",
            format!("`{}` of {n} sounds with {w} weights", b.call.name),
            b.origin,
        )
        .label(sounds.span, format!("{n} lanes"))
        .label(weights.span, format!("{w} lanes"))
        .help("give one weight per sound: (importance (vector a b c) (vector 3 2 1))"))
}

/// Σ sᵢ·wᵢ/Σwᵢ with negative weights as 0, and the mean when no weight is positive.
fn importance(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let n = check_sounds_and_weights(l, b)?;
    let [sounds, weights] = b.nodes()[..] else {
        unreachable!("two parameters")
    };
    let zero = l.graph.constant(0.0);
    // max(NaN, 0) is 0: a NaN weight counts as 0 too.
    let positive = l.graph.add(Op::Binary(BinaryOp::Max), vec![weights, zero]);
    let total = l.graph.add(Op::Combine, vec![positive]);
    let scaled = l
        .graph
        .add(Op::Binary(BinaryOp::Mul), vec![sounds, positive]);
    let mix = l.graph.add(Op::Combine, vec![scaled]);
    let weighted = l.graph.add(Op::Binary(BinaryOp::Div), vec![mix, total]);
    let sum = l.graph.add(Op::Combine, vec![sounds]);
    let one_nth = l.graph.constant(1.0 / n as f64);
    let mean = l.graph.add(Op::Binary(BinaryOp::Mul), vec![sum, one_nth]);
    let any = l.graph.add(Op::Binary(BinaryOp::Gt), vec![total, zero]);
    Ok(l.graph
        .add(Op::Ternary(TernaryOp::If), vec![any, weighted, mean]))
}

fn importance_locked(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let sounds = l.const_count(&b.args[0], "the number of sounds", b.origin)?;
    let locked = &b.args[1..];
    let percents = locked
        .iter()
        .map(|arg| l.const_number(arg, "a locked percentage", b.origin))
        .collect::<Result<Vec<f64>, Diag>>()?;
    let bad = |message: String, span, label: String, help: String| {
        l.diag("timbre::bad-importance", message, b.origin)
            .label(span, label)
            .help(help)
    };
    match locked_weights(sounds, &percents) {
        Ok(weights) => Ok(l.graph.const_vector(weights)),
        Err(LockError::TooMany { sounds, locked: k }) => Err(bad(
            format!("{k} locked percentages for {sounds} sounds"),
            locked[sounds].span,
            "no sound left for this one".into(),
            "lock at most one percentage per sound".into(),
        )),
        Err(LockError::Invalid { index }) => Err(bad(
            format!("locked percentage {} is negative", percents[index]),
            locked[index].span,
            "below 0 %".into(),
            "a percentage is 0 to 100".into(),
        )),
        Err(LockError::OverFull { index, total }) => {
            let before: f64 = percents[..index].iter().sum();
            Err(bad(
                format!("locked percentages add up to {total} %, over 100 %"),
                locked[index].span,
                format!("{} % were left here", 100.0 - before),
                format!(
                    "the locked percentages share 100 %: lock at most {} % here",
                    100.0 - before
                ),
            ))
        }
        Err(LockError::Remainder { total }) => Err(bad(
            format!("every sound is locked but they add up to {total} %"),
            b.call.span,
            format!("{total} %, not 100 %"),
            "lock one sound fewer: the next sound takes the remainder".into(),
        )),
    }
}

fn inverse_importance(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    check_sounds_and_weights(l, b)?;
    l.check_one_lane(&b.args[2], "the switch", b.origin)?;
    l.check_one_lane(&b.args[3], "the transition time", b.origin)?;
    Ok(l.stateful(InverseImportance, b.nodes()))
}

/// The source is copied into a graph of its own, rendered on the node's clock.
fn energetic(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    l.check_one_lane(&b.args[0], "the speed", b.origin)?;
    let source = &b.args[1];
    let w = l.graph.width(source.node);
    if w != 1 {
        return Err(l
            .diag(
                "timbre::width-mismatch",
                format!("the replayed sound is {w} lanes wide"),
                b.origin,
            )
            .label(source.span, format!("{w} lanes"))
            .help("replay one lane: sum the lanes with (combine …), or replay each lane"));
    }
    let (graph, root) = l.graph.subgraph(source.node);
    let kernel = Energetic {
        source: Arc::new(graph),
        root,
    };
    Ok(l.stateful(kernel, vec![b.args[0].node]))
}

fn sputter(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let what = ["the start rate", "the end rate", "the sweep's duration"];
    for (arg, what) in b.args.iter().zip(what) {
        l.check_one_lane(arg, what, b.origin)?;
    }
    let curve = match l.const_number(&b.args[3], "the sweep's curve", b.origin)? {
        0.0 => SweepCurve::Linear,
        1.0 => SweepCurve::Exponential,
        other => {
            return Err(l
                .diag(
                    "timbre::bad-sputter",
                    format!("`sputter` has no curve {other}"),
                    b.origin,
                )
                .label(b.args[3].span, "not 0 or 1")
                .help("write :curve 0 for a linear sweep or :curve 1 for an exponential one"))
        }
    };
    Ok(l.stateful(Sputter { curve }, b.nodes()[..3].to_vec()))
}

/// The longest delay of a delay line, in seconds: the `max` argument (at `max`) if
/// given, else the longest of a constant delay time (at `time`).
fn max_delay(l: &Lowerer<'_>, b: &Bound<'_>, time: usize, max: usize) -> Result<f64, Diag> {
    let (time, max) = (&b.args[time], &b.args[max]);
    let seconds = match (max.given, l.graph.const_value(time.node)) {
        (true, _) => l.const_number(max, "the maximum delay", b.origin)?,
        (false, Some(times)) => times.iter().copied().fold(0.0, f64::max),
        (false, None) => {
            return Err(l
                .diag(
                    "timbre::delay-needs-max",
                    "a varying delay time needs a maximum",
                    b.origin,
                )
                .label(time.span, "this delay time changes")
                .help(format!(
                    "give the longest delay in seconds with `:max`, e.g. ({} … :max 0.5)",
                    b.call.name
                )))
        }
    };
    if !(0.0..=MAX_BUFFER_SECONDS).contains(&seconds) {
        let span = if max.given { max.span } else { time.span };
        return Err(l
            .diag(
                "timbre::bad-delay",
                format!("maximum delay {seconds} s is out of range"),
                b.origin,
            )
            .label(span, "out of range")
            .help(format!("delays may be 0 to {MAX_BUFFER_SECONDS} seconds")));
    }
    Ok(seconds)
}

impl Lowerer<'_> {
    /// A stateful kernel's node.
    pub(crate) fn stateful(
        &mut self,
        kernel: impl timbre_ir::kernel::StatefulKernel,
        args: Vec<NodeId>,
    ) -> NodeId {
        self.graph.add(Op::Stateful(Arc::new(kernel)), args)
    }

    /// `op` folded from the left over one or more nodes. A run of one-lane constants
    /// is folded here, as the graph would fold it, without a node per step (a call of
    /// a million numbers makes one constant, not a million).
    pub(crate) fn fold(&mut self, op: BinaryOp, nodes: &[NodeId]) -> NodeId {
        let scalar = |graph: &timbre_ir::Graph, id: NodeId| match graph.node(id).as_const() {
            Some([x]) => Some(*x),
            _ => None,
        };
        let mut acc = nodes[0];
        let mut k = 1;
        while k < nodes.len() {
            if let Some(mut value) = scalar(&self.graph, acc) {
                let start = k;
                while let Some(x) = nodes.get(k).and_then(|n| scalar(&self.graph, *n)) {
                    value = op.apply(value, x);
                    k += 1;
                }
                if k > start {
                    acc = self.graph.constant(value);
                    continue;
                }
            }
            acc = self.graph.add(Op::Binary(op), vec![acc, nodes[k]]);
            k += 1;
        }
        acc
    }
}

/// Names other languages give to what timbre has under another name: (their name,
/// lowercase; timbre's; how timbre writes it). `unknown function` suggests these.
pub const ALIASES: &[(&str, &str, &str)] = &[
    ("sinosc", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("sinwave", "sine", "write `(sine (* t f))`: timbre's `sine` takes a phase in cycles"),
    ("sinewave", "sine", "write `(sine (* t f))`: timbre's `sine` takes a phase in cycles"),
    ("osc", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("oscil", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("oscili", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("poscil", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("os.osc", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("hzosc", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("sin-osc", "sine", "write `(sine (phasor f))`: timbre's `sine` takes a phase in cycles"),
    ("saw", "saw-bl", "write `(saw-bl (phasor f))`, or `(sawtooth …)` for the naive one"),
    ("lfsaw", "sawtooth", "write `(sawtooth (phasor f))`"),
    ("vco2", "saw-bl", "write `(saw-bl (phasor f))`"),
    ("osc-saw", "saw-bl", "write `(saw-bl (phasor f))`"),
    ("pulse-osc", "pulse", "write `(pulse (phasor f) width)`"),
    ("lfpulse", "pulse", "write `(pulse (phasor f) width)`"),
    ("lftri", "triangle", "write `(triangle (phasor f))`"),
    ("tri", "triangle", "write `(triangle (phasor f))`"),
    ("whitenoise", "white", "write `(white)`"),
    ("rand", "white", "write `(white)`"),
    ("pinknoise", "pink", "write `(pink)`"),
    ("pinkish", "pink", "write `(pink)`"),
    ("lfnoise0", "latch", "stepped random: `(latch (white) (square (* t rate)))`"),
    ("randh", "latch", "stepped random: `(latch (white) (square (* t rate)))`"),
    ("lfnoise1", "noise", "smooth random: `(noise (* t 2 rate))`"),
    ("lfnoise2", "noise", "smooth random: `(noise (* t 2 rate))`"),
    ("randi", "noise", "smooth random: `(noise (* t 2 rate))`"),
    ("lpf", "lowpass", "write `(lowpass x freq)`"),
    ("rlpf", "lowpass", "write `(lowpass x freq :q q)`"),
    ("lp", "lowpass", "write `(lowpass x freq)`"),
    ("butlp", "lowpass", "write `(lowpass x freq)`"),
    ("moogladder", "lowpass", "write `(lowpass x freq :q q)`"),
    ("hpf", "highpass", "write `(highpass x freq)`"),
    ("hp", "highpass", "write `(highpass x freq)`"),
    ("bpf", "bandpass", "write `(bandpass x freq)`"),
    ("reson", "resonator", "write `(resonator x freq bandwidth)`"),
    ("delayn", "delay", "write `(delay x seconds)`"),
    ("delayl", "delay", "write `(delay x seconds)`"),
    ("delayc", "delay", "write `(delay x seconds)`"),
    ("vdelay", "delay", "write `(delay x seconds)`"),
    ("combn", "comb", "write `(comb x delay feedback)`"),
    ("combl", "comb", "write `(comb x delay feedback)`"),
    ("allpassn", "allpass", "write `(allpass x delay gain)`"),
    ("envgen", "env", "`(env t attack decay)`, or `(adsr gate a d s r)` with a gate"),
    ("line", "env", "`(env t attack decay)`, or keyframes for a curve over the scene"),
    ("linseg", "env", "`(env t attack decay)`, or keyframes for a curve over the scene"),
    ("expseg", "env", "`(env t attack decay :decay-curve -5)`"),
    ("pwl", "env", "`(env t attack decay)`, or keyframes for a curve over the scene"),
    ("madsr", "adsr", "write `(adsr gate attack decay sustain release)`"),
    ("pan2", "pan", "write `(pan position x)`, position from −1 (left) to 1 (right)"),
    ("port", "lag", "write `(lag x seconds)`"),
    ("klank", "combine", "a mode bank is a sum over lanes: `(combine (* amps (sine (* t freqs)) (damp (/ (* 6.91 t) t60s))))`"),
    ("mix", "combine", "`(combine x)` sums the lanes of x; `(+ a b)` sums trees"),
    ("midicps", "midihz", "write `(midihz note)`"),
    ("cpsmidinn", "midihz", "write `(midihz note)`"),
    ("playbuf", "sample", "write `(sample \"file.wav\")`"),
    ("diskin", "sample", "write `(sample \"file.wav\")`"),
    ("diskin2", "sample", "write `(sample \"file.wav\")`"),
    ("convolution", "conv", "write `(conv x \"response.wav\")`"),
    ("pconvolve", "conv", "write `(conv x \"response.wav\")`"),
];

/// What another language's `name` is in timbre: the node and how to write it.
pub fn alias(name: &str) -> Option<(&'static str, &'static str)> {
    let lower = name.to_ascii_lowercase();
    let bare = lower.trim_end_matches(".ar").trim_end_matches(".kr");
    ALIASES
        .iter()
        .find(|(other, ..)| *other == bare)
        .map(|(_, ours, how)| (*ours, *how))
}
