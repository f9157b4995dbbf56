//! The builders of the physical models (`tube-modes`, `impact`, `scrape`, `roll`): nodes whose
//! arguments may name a material of [`timbre_ir::dsp::materials`], written as that
//! material's constants before the call is bound.

use timbre_diag::Diag;
use timbre_ir::dsp::contact_force::{
    ContactForce, Motion, OutOfRange, Quantity as ContactQuantity, Roller, Surface,
};
use timbre_ir::dsp::impact::{Bodies, ImpactError, Quantity as ImpactQuantity};
use timbre_ir::dsp::materials;
use timbre_ir::dsp::tube::{Quantity, Tube, TubeError, MATERIALS};
use timbre_ir::NodeId;
use timbre_syntax::{Expr, ExprKind};

use super::{lookup, opt, p, Param};
use crate::lower::{did_you_mean, Bound, Call, Lowerer, Origin, Scope, Seed};

/// `tube-modes` with `:material NAME` written as that material's `:youngs` and
/// `:density`, then bound as any call.
pub(super) fn tube_modes_form(
    l: &mut Lowerer<'_>,
    call: &Call<'_>,
    origin: &Origin,
    scope: &mut Scope,
) -> Result<NodeId, Diag> {
    let names: Vec<&str> = MATERIALS.iter().map(|m| m.name).collect();
    let mut args: Vec<Expr> = vec![];
    let mut i = 0;
    while i < call.args.len() {
        let arg = &call.args[i];
        let (ExprKind::Keyword(key), Some(value)) = (&arg.kind, call.args.get(i + 1)) else {
            args.push(arg.clone());
            i += 1;
            continue;
        };
        if key != "material" {
            args.extend([arg.clone(), value.clone()]);
            i += 2;
            continue;
        }
        let material = value
            .as_symbol()
            .and_then(|name| MATERIALS.iter().find(|m| m.name == name));
        let Some(material) = material else {
            return Err(l
                .diag(
                    "timbre::bad-tube",
                    match value.as_symbol() {
                        Some(name) => format!("unknown material `{name}`"),
                        None => format!("a material is a name, not {}", value.describe()),
                    },
                    origin,
                )
                .label(value.span, "not a material")
                .help(format!(
                    "the materials are {}; or give :youngs and :density",
                    names.join(", ")
                )));
        };
        let explicit = call
            .args
            .iter()
            .find(|a| matches!(&a.kind, ExprKind::Keyword(k) if k == "youngs" || k == "density"));
        if let Some(explicit) = explicit {
            return Err(l
                .diag(
                    "timbre::duplicate-argument",
                    "the material is given twice",
                    origin,
                )
                .label(value.span, "a named material")
                .label(explicit.span, "and its own constants")
                .help("give :material, or :youngs and :density"));
        }
        let at = |kind| Expr::new(kind, value.span);
        args.extend([
            at(ExprKind::Keyword("youngs".into())),
            at(ExprKind::Number(material.youngs)),
            at(ExprKind::Keyword("density".into())),
            at(ExprKind::Number(material.density)),
        ]);
        i += 2;
    }
    let spec = lookup("tube-modes").expect("in the catalogue");
    let call = Call {
        args: &args,
        ..*call
    };
    let bound = l.bind_args(&call, spec.params, false, false, origin, scope)?;
    let bound = Bound {
        call: &call,
        args: bound.args.into_iter().flatten().collect(),
        seed: Seed::Key(None),
        origin,
    };
    tube_modes(l, &bound)
}

/// The modal frequencies of a tube (`dsp::tube`): `n` constant lanes, in Hz.
fn tube_modes(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let what = [
        "the number of modes",
        Quantity::Length.describe(),
        Quantity::Outer.describe(),
        Quantity::Inner.describe(),
        Quantity::Youngs.describe(),
        Quantity::Density.describe(),
    ];
    for (arg, what) in b.args.iter().zip(what) {
        l.check_one_lane(arg, what, b.origin)?;
    }
    let n = l.const_count(&b.args[0], what[0], b.origin)?;
    let mut values = [0.0; 5];
    for (k, value) in values.iter_mut().enumerate() {
        *value = l.const_number(&b.args[k + 1], what[k + 1], b.origin)?;
    }
    let [length, outer, inner, youngs, density] = values;
    let tube = Tube {
        length,
        outer,
        inner,
        youngs,
        density,
    };
    let error = match tube.modes(n) {
        Ok(modes) => return Ok(l.graph.const_vector(modes)),
        Err(error) => error,
    };
    let bad = |message: String| l.diag("timbre::bad-tube", message, b.origin);
    Err(match error {
        TubeError::OutOfRange(quantity, x) => {
            let (arg, bound, label, help) = match quantity {
                Quantity::Length => (1, "above 0", "not above 0", DIMENSIONS),
                Quantity::Outer => (2, "above 0", "not above 0", DIMENSIONS),
                Quantity::Inner => (3, "0 (a solid rod) or more", "below 0", DIMENSIONS),
                Quantity::Youngs => (4, "above 0", "not above 0", MATERIAL),
                Quantity::Density => (5, "above 0", "not above 0", MATERIAL),
            };
            bad(format!("{} must be {bound}, not {x}", quantity.describe()))
                .label(b.args[arg].span, label)
                .help(help)
        }
        TubeError::InnerNotBelowOuter { outer, inner } => bad(format!(
            "the tube's inner diameter {inner} m is not less than its outer diameter {outer} m"
        ))
        .label(b.args[3].span, "the inner diameter")
        .label(b.args[2].span, "the outer diameter")
        .help("the inner diameter is the bore: less than the outer one, or 0 for a solid rod"),
        TubeError::NotFinite { mode, hz } => bad(format!(
            "the tube's mode {mode} is {hz} Hz: the quantities are out of range"
        ))
        .label(b.call.span, "no finite frequency above 0 Hz")
        .help(format!("{DIMENSIONS}; {MATERIAL}")),
    })
}

/// Help for a tube's dimensions, and for its material.
const DIMENSIONS: &str = "lengths and diameters are in metres: (tube-modes 5 0.3 0.025 0.022)";
const MATERIAL: &str =
    "Young's modulus is in pascals and the density in kg/m³: aluminium is :youngs 69e9 :density 2700";

/// `impact`'s parameters, in the order of [`ImpactQuantity`]: body b's radius and
/// mass default to +∞ (a flat surface, an immovable one).
pub(super) const IMPACT_PARAMS: &[Param<'static>] = &[
    p("youngs"),
    p("poisson"),
    p("youngs-b"),
    p("poisson-b"),
    p("radius"),
    opt("radius-b", f64::INFINITY),
    p("mass"),
    opt("mass-b", f64::INFINITY),
    p("speed"),
];

/// The keywords a material of each body stands for in `impact`: `:a NAME` is
/// `:youngs E :poisson ν`, `:b NAME` is `:youngs-b E :poisson-b ν`.
const IMPACT_MATERIALS: [(&str, &str, &str); 2] =
    [("a", "youngs", "poisson"), ("b", "youngs-b", "poisson-b")];

/// What each required `impact` keyword is, for a call that leaves it out.
const IMPACT_REQUIRED: [(&str, &str); 5] = [
    (
        "youngs",
        "the material of body a: :a steel (or :youngs and :poisson)",
    ),
    (
        "youngs-b",
        "the material of body b: :b oak (or :youngs-b and :poisson-b)",
    ),
    (
        "radius",
        "body a's radius of curvature at the contact in metres: :radius 0.01",
    ),
    ("mass", "body a's mass in kilograms: :mass 0.03"),
    (
        "speed",
        "the normal speed at which the bodies meet, in m/s: :speed 1",
    ),
];

/// A call's arguments with each material keyword of `materials` (`:a NAME`) written
/// as the material's modulus and Poisson's ratio under their own keywords.
fn expand_materials(
    l: &Lowerer<'_>,
    call: &Call<'_>,
    origin: &Origin,
    materials: &[(&str, &str, &str)],
) -> Result<Vec<Expr>, Diag> {
    let mut args: Vec<Expr> = vec![];
    let mut i = 0;
    while i < call.args.len() {
        let arg = &call.args[i];
        let (Some(key), Some(value)) = (keyword_of(arg), call.args.get(i + 1)) else {
            args.push(arg.clone());
            i += 1;
            continue;
        };
        i += 2;
        let Some(&(_, youngs, poisson)) = materials.iter().find(|m| m.0 == key) else {
            args.extend([arg.clone(), value.clone()]);
            continue;
        };
        let material = named_material(l, value, origin)?;
        let explicit = call
            .args
            .iter()
            .find(|a| matches!(&a.kind, ExprKind::Keyword(k) if k == youngs || k == poisson));
        if let Some(explicit) = explicit {
            return Err(l
                .diag(
                    "timbre::duplicate-argument",
                    format!("the material of body {key} is given twice"),
                    origin,
                )
                .label(value.span, "a named material")
                .label(explicit.span, "and its own constants")
                .help(format!("give :{key}, or :{youngs} and :{poisson}")));
        }
        let at = |kind| Expr::new(kind, value.span);
        args.extend([
            at(ExprKind::Keyword(youngs.into())),
            at(ExprKind::Number(material.youngs)),
            at(ExprKind::Keyword(poisson.into())),
            at(ExprKind::Number(material.poisson)),
        ]);
    }
    Ok(args)
}

fn keyword_of(arg: &Expr) -> Option<String> {
    match &arg.kind {
        ExprKind::Keyword(key) => Some(key.clone()),
        _ => None,
    }
}

/// `impact` with `:a NAME` and `:b NAME` written as the materials' moduli and
/// Poisson's ratios, then bound as any call.
pub(super) fn impact_form(
    l: &mut Lowerer<'_>,
    call: &Call<'_>,
    origin: &Origin,
    scope: &mut Scope,
) -> Result<NodeId, Diag> {
    let args = expand_materials(l, call, origin, &IMPACT_MATERIALS)?;
    let positional = args.iter().any(|a| keyword_of(a).is_none())
        && !args.iter().any(|a| keyword_of(a).is_some());
    let given = |name: &str| args.iter().any(|a| keyword_of(a).as_deref() == Some(name));
    if !positional {
        if let Some((_, what)) = IMPACT_REQUIRED.iter().find(|(name, _)| !given(name)) {
            return Err(l
                .diag(
                    "timbre::bad-impact",
                    format!("`impact` needs {what}"),
                    origin,
                )
                .label(call.span, "this impact")
                .help("e.g. (impact :a steel :b oak :radius 0.01 :mass 0.03 :speed 1)"));
        }
    }
    let call = Call {
        args: &args,
        ..*call
    };
    let bound = l.bind_args(&call, IMPACT_PARAMS, false, false, origin, scope)?;
    let bound = Bound {
        call: &call,
        args: bound.args.into_iter().flatten().collect(),
        seed: Seed::Key(None),
        origin,
    };
    impact(l, &bound)
}

/// The material `value` names, or a diagnostic with the closest name.
pub(crate) fn named_material(
    l: &Lowerer<'_>,
    value: &Expr,
    origin: &Origin,
) -> Result<&'static materials::Material, Diag> {
    let name = value.as_symbol();
    if let Some(material) = name.and_then(materials::material) {
        return Ok(material);
    }
    let all = materials::names().collect::<Vec<_>>().join(", ");
    let diag = match name {
        Some(name) => l
            .diag(
                "timbre::unknown-material",
                format!("unknown material `{name}`"),
                origin,
            )
            .label(value.span, "not a material of the table"),
        None => l
            .diag(
                "timbre::unknown-material",
                format!("a material is a name, not {}", value.describe()),
                origin,
            )
            .label(value.span, "not a material"),
    };
    let suggestion = name.and_then(|name| did_you_mean(name, materials::names()));
    Err(match suggestion {
        Some(close) => diag.help(format!("did you mean `{close}`? The materials are {all}")),
        None => diag.help(format!("the materials are {all}")),
    })
}

/// The Hertz force of one impact (`dsp::impact`), in newtons.
fn impact(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    use ImpactQuantity::*;
    let order = [
        YoungsA, PoissonA, YoungsB, PoissonB, RadiusA, RadiusB, MassA, MassB, Speed,
    ];
    let mut values = [0.0; 9];
    for ((value, arg), quantity) in values.iter_mut().zip(&b.args).zip(order) {
        l.check_one_lane(arg, quantity.describe(), b.origin)?;
        // Any constant, finite or not: `Bodies::impact` says which may be +∞.
        *value = match l.graph.scalar(arg.node) {
            Some(x) => x,
            None => l.const_number(arg, quantity.describe(), b.origin)?,
        };
    }
    let [youngs_a, poisson_a, youngs_b, poisson_b, radius_a, radius_b, mass_a, mass_b, speed] =
        values;
    let bodies = Bodies {
        youngs_a,
        poisson_a,
        youngs_b,
        poisson_b,
        radius_a,
        radius_b,
        mass_a,
        mass_b,
        speed,
    };
    let bad = |message: String| l.diag("timbre::bad-impact", message, b.origin);
    match bodies.impact() {
        Ok(kernel) => Ok(l.stateful(kernel, vec![])),
        Err(ImpactError::OutOfRange(quantity, x)) => {
            let k = order.iter().position(|q| *q == quantity).unwrap_or(0);
            let (bound, help) = match quantity {
                PoissonA | PoissonB => (
                    "above −1 and at most 0.5",
                    "Poisson's ratio of a solid is between −1 and 0.5 (steel 0.29, rubber 0.49)",
                ),
                YoungsA | YoungsB => (
                    "above 0 and finite",
                    "Young's modulus is in pascals (steel 200e9); or name a material with :a or :b",
                ),
                RadiusB | MassB => (
                    "above 0",
                    "leave :radius-b out for a flat surface and :mass-b for an immovable one",
                ),
                _ => (
                    "above 0 and finite",
                    "radii are in metres, masses in kilograms and the speed in m/s",
                ),
            };
            Err(bad(format!("{} must be {bound}, not {x}", quantity.describe()))
                .label(b.args[k].span, format!(":{} {x}", quantity.keyword()))
                .help(help))
        }
        Err(ImpactError::NotFinite) => Err(bad(
            "the impact's force or duration is not finite and above 0: the quantities are out of range"
                .into(),
        )
        .label(b.call.span, "this impact")
        .help("radii are in metres, masses in kilograms, moduli in pascals and the speed in m/s")),
    }
}

/// The parameters `scrape` and `roll` share after `speed` and `force`: the surface,
/// in the order of [`Surface::quantities`]. `impacts` is the node's own.
const fn surface_params(impacts: f64) -> [Param<'static>; 5] {
    [
        opt("roughness", DEFAULT_ROUGHNESS),
        opt("grain", DEFAULT_GRAIN),
        opt("period", 0.0),
        opt("impacts", impacts),
        opt("hold", DEFAULT_HOLD),
    ]
}

/// The documented defaults: a fine machined or sanded surface (1 µm rms, features down
/// to 0.1 mm), a probe held down at about 10 g.
const DEFAULT_ROUGHNESS: f64 = 1e-6;
const DEFAULT_GRAIN: f64 = 1e-4;
const DEFAULT_HOLD: f64 = 100.0;

/// Micro-impacts per metre slid, and rolled (none: a rolling body does not chatter).
const SCRAPE_IMPACTS: f64 = 200.0;
const ROLL_IMPACTS: f64 = 0.0;

const SURFACE_SCRAPE: [Param<'static>; 5] = surface_params(SCRAPE_IMPACTS);
const SURFACE_ROLL: [Param<'static>; 5] = surface_params(ROLL_IMPACTS);

/// `scrape`'s parameters: speed, force, then the surface.
pub(super) const SCRAPE_PARAMS: &[Param<'static>] = &[
    p("speed"),
    p("force"),
    SURFACE_SCRAPE[0],
    SURFACE_SCRAPE[1],
    SURFACE_SCRAPE[2],
    SURFACE_SCRAPE[3],
    SURFACE_SCRAPE[4],
];

/// `roll`'s parameters: speed, force, the surface, then the rolling body's radius and
/// the materials (steel on steel unless given).
pub(super) const ROLL_PARAMS: &[Param<'static>] = &[
    p("speed"),
    p("force"),
    SURFACE_ROLL[0],
    SURFACE_ROLL[1],
    SURFACE_ROLL[2],
    SURFACE_ROLL[3],
    SURFACE_ROLL[4],
    p("radius"),
    opt("youngs", materials::STEEL.youngs),
    opt("poisson", materials::STEEL.poisson),
    opt("youngs-b", materials::STEEL.youngs),
    opt("poisson-b", materials::STEEL.poisson),
];

/// `scrape`: a probe sliding on a rough surface (`dsp::contact_force`).
pub(super) fn scrape(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    contact_force(l, b, None)
}

/// `roll` with `:a NAME` and `:b NAME` written as the materials' constants, then
/// bound as any call (with `:seed`).
pub(super) fn roll_form(
    l: &mut Lowerer<'_>,
    call: &Call<'_>,
    origin: &Origin,
    scope: &mut Scope,
) -> Result<NodeId, Diag> {
    let args = expand_materials(l, call, origin, &IMPACT_MATERIALS)?;
    let call = Call {
        args: &args,
        ..*call
    };
    let bound = l.bind_args(&call, ROLL_PARAMS, false, true, origin, scope)?;
    let seed = match (&bound.keyword_seed, bound.seed_bits) {
        (_, Some(bits)) => Seed::Bits(bits),
        (Some(arg), None) => Seed::Key(Some(l.const_integer(arg, "seed", origin)?)),
        (None, None) => Seed::Key(None),
    };
    let bound = Bound {
        call: &call,
        args: bound.args.into_iter().flatten().collect(),
        seed,
        origin,
    };
    let values = contact_constants(l, &bound, 7, 5)?;
    let roller = Roller {
        radius: values[0],
        youngs_a: values[1],
        poisson_a: values[2],
        youngs_b: values[3],
        poisson_b: values[4],
    };
    contact_force(l, &bound, Some(roller))
}

/// The constants of `count` arguments from `first` on, each of one lane (any number,
/// finite or not: `ContactForce::new` says which are in range).
fn contact_constants(
    l: &mut Lowerer<'_>,
    b: &Bound<'_>,
    first: usize,
    count: usize,
) -> Result<Vec<f64>, Diag> {
    let mut values = vec![];
    for arg in &b.args[first..first + count] {
        let what = "a constant of the contact";
        l.check_one_lane(arg, what, b.origin)?;
        let value = match l.graph.scalar(arg.node) {
            Some(x) => x,
            None => l.const_number(arg, what, b.origin)?,
        };
        values.push(value);
    }
    Ok(values)
}

/// The `scrape` (no roller) or `roll` node of bound arguments: speed, force, the
/// surface's five constants, then the roller's.
fn contact_force(
    l: &mut Lowerer<'_>,
    b: &Bound<'_>,
    roller: Option<Roller>,
) -> Result<NodeId, Diag> {
    let name = if roller.is_some() { "roll" } else { "scrape" };
    l.check_one_lane(&b.args[0], "the slip speed", b.origin)?;
    l.check_one_lane(&b.args[1], "the normal force", b.origin)?;
    let values = contact_constants(l, b, 2, 5)?;
    let seed = l.random_seed(name, b, &[]);
    let surface = Surface {
        roughness: values[0],
        grain: values[1],
        period: values[2],
        impacts: values[3],
        hold: values[4],
        seed,
    };
    let motion = match roller {
        Some(roller) => Motion::Roll(roller),
        None => Motion::Scrape,
    };
    match ContactForce::new(surface, motion) {
        Ok(kernel) => Ok(l.stateful(kernel, vec![b.args[0].node, b.args[1].node])),
        Err(OutOfRange(quantity, x)) => {
            use ContactQuantity::*;
            let k = match quantity {
                Roughness => 2,
                Grain => 3,
                Period => 4,
                Impacts => 5,
                Hold => 6,
                Radius => 7,
                YoungsA => 8,
                PoissonA => 9,
                YoungsB => 10,
                PoissonB => 11,
            };
            let help = match quantity {
                Roughness | Grain | Period => {
                    "lengths are in metres: a fine surface is :roughness 1e-6 :grain 1e-4; \
                     :period 0 is no groove"
                }
                Impacts => "micro-impacts are counted per metre slid: :impacts 200, or 0 for none",
                Hold => "the hold is the acceleration in m/s² the normal force gives the probe: :hold 100",
                Radius => "the rolling body's radius of curvature at the contact is in metres: :radius 0.01",
                PoissonA | PoissonB => {
                    "Poisson's ratio of a solid is between −1 and 0.5 (steel 0.29, rubber 0.49)"
                }
                YoungsA | YoungsB => {
                    "Young's modulus is in pascals (steel 200e9); or name a material with :a or :b"
                }
            };
            let span = b.args.get(k).map_or(b.call.span, |arg| arg.span);
            Err(l
                .diag(
                    "timbre::bad-contact-force",
                    format!(
                        "`{name}`: {} must be {}, not {x}",
                        quantity.describe(),
                        quantity.range()
                    ),
                    b.origin,
                )
                .label(span, format!(":{} {x}", quantity.keyword()))
                .help(help))
        }
    }
}
