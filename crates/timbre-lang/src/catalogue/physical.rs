//! The builders of the physical models (`tube-modes`, `impact`): nodes whose
//! arguments may name a material of [`timbre_ir::dsp::materials`], written as that
//! material's constants before the call is bound.

use timbre_diag::Diag;
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

/// `impact` with `:a NAME` and `:b NAME` written as the materials' moduli and
/// Poisson's ratios, then bound as any call.
pub(super) fn impact_form(
    l: &mut Lowerer<'_>,
    call: &Call<'_>,
    origin: &Origin,
    scope: &mut Scope,
) -> Result<NodeId, Diag> {
    let keyword_of = |arg: &Expr| match &arg.kind {
        ExprKind::Keyword(key) => Some(key.clone()),
        _ => None,
    };
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
        let Some(&(_, youngs, poisson)) = IMPACT_MATERIALS.iter().find(|m| m.0 == key) else {
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
fn named_material(
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
