//! Contacts found in a shot's meshes, sounded: `(contacts shot :materials (("Cube"
//! oak) ("Floor" concrete)))` finds every impact, slide and roll between the objects
//! it names (`timbre_motion::contacts`) and makes, for each object of each contact,
//! an instance driven by the force a physicist would write down:
//!
//! - an impact: the Hertz pulse of the two materials (`impact`), with the local radii,
//!   masses and normal speed found;
//! - a sustained contact: `scrape` at the slip speed while it slides and `roll` at the
//!   rolling speed while it rolls, each scaled by the normal force, their weights
//!   moving linearly between keys so that a change of kind makes no click.
//!
//! The force drives the object's sound: a class of `:sounds` (called with `:force`),
//! the modes of its own shape (`:modal`: its mesh and material analysed by
//! `timbre_modal`, struck where the contact is, along its normal), or the preset of
//! its material ([`preset`]). An impact is heard from its world point; a sustained
//! contact from the object's origin as it moves.

use std::sync::Arc;

use glam::DVec3;
use timbre_diag::Diag;
use timbre_ir::dsp::impact::Bodies as HertzBodies;
use timbre_ir::dsp::materials::Material;
use timbre_ir::keyframes::{Interpolation, KeyframeTrack};
use timbre_ir::op::{FadeIn, Op};
use timbre_ir::space::Path;
use timbre_ir::{NodeId, Stem};
use timbre_modal::model::{Model, Settings as ModalSettings, Strike, AIR_DENSITY};
use timbre_modal::shape::{Resolution, Shape};
use timbre_motion::contacts::{
    self, Body, ContactError, ContactKind, ContactOptions, ContactSample, Contacts, Impact,
};
use timbre_motion::{NodeIndex, Shot};
use timbre_syntax::{Expr, ExprKind, Span};

use super::build::{keyword, list, number, resonator_bank, symbol};
use super::modal::{catalogue_material, modal_code, shot_mesh};
use super::motion::NodeRef;
use super::scene::{Names, Options, Timing};
use super::{Lowerer, Origin, Scope};

const USAGE: &str = "(contacts shot :materials ((\"Cube\" oak) (\"Floor\" concrete)))";

/// The pressure at 1 m (Pa) that a preset writes as full scale (120 dB SPL).
pub(crate) const FULL_SCALE_PA: f64 = 20.0;
/// Modes of a preset.
const PRESET_MODES: usize = 24;
/// Default frames per second of the score's frame column.
const DEFAULT_FRAME_RATE: f64 = 24.0;
/// The rms roughness of the surfaces that slide and roll, m: a sawn or cast finish
/// (wood, concrete), rougher than `scrape`'s own default of a polished 1 µm.
const DEFAULT_ROUGHNESS: f64 = 1e-5;
/// How long a sustained contact's force takes to rise from and fall back to 0 at its
/// ends, seconds.
const RAMP: f64 = 0.005;

/// One row of the contact score (`timbre check --contacts`).
#[derive(Clone, Debug, PartialEq)]
pub struct ContactRow {
    /// Scene time, seconds.
    pub time: f64,
    /// "impact", "slide" or "roll".
    pub kind: &'static str,
    pub a: String,
    pub b: String,
    /// m/s: the approach speed of an impact, 0 for a sustained contact.
    pub normal_speed: f64,
    /// m/s: sliding speed (of an impact, just before it).
    pub slip_speed: f64,
    /// m/s.
    pub rolling_speed: f64,
    /// N·s (impacts).
    pub impulse: f64,
    /// N: the peak Hertz force of an impact, the mean normal force of a slide or roll.
    pub force: f64,
    /// World point, m.
    pub point: DVec3,
    /// Seconds a slide or roll lasts; 0 for an impact.
    pub length: f64,
}

/// What one `contacts` form found.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundContacts {
    /// The motion file's name.
    pub shot: String,
    pub frame_rate: f64,
    /// The frame at scene time 0 (`:first-frame`).
    pub first_frame: f64,
    /// In time order.
    pub rows: Vec<ContactRow>,
    /// How many instances the form made.
    pub instances: usize,
    /// The objects of `:modal`, each with the model of its shape.
    pub shapes: Vec<(String, Arc<Model>)>,
}

impl FoundContacts {
    /// The frame, counted as `:frame-rate` and `:first-frame` say, shown at `time`.
    pub fn frame_of(&self, time: f64) -> f64 {
        self.first_frame + time * self.frame_rate
    }
}

/// The contact score of `found` as tab-separated values, one header line then one
/// line per contact in time order.
pub fn contact_score(found: &[FoundContacts]) -> String {
    let mut text = String::from(
        "shot\ttime\tframe\tkind\ta\tb\tnormal-speed\tslip-speed\trolling-speed\timpulse\tforce\tlength\tx\ty\tz\n",
    );
    for f in found {
        for r in &f.rows {
            text += &format!(
                "{}\t{:.6}\t{:.3}\t{}\t{}\t{}\t{:.4}\t{:.4}\t{:.4}\t{:.6}\t{:.3}\t{:.4}\t{:.4}\t{:.4}\t{:.4}\n",
                f.shot,
                r.time,
                f.frame_of(r.time),
                r.kind,
                r.a,
                r.b,
                r.normal_speed,
                r.slip_speed,
                r.rolling_speed,
                r.impulse,
                r.force,
                r.length,
                r.point.x,
                r.point.y,
                r.point.z
            );
        }
    }
    text
}

/// An object taking part: its node, material and sound.
struct Object {
    name: String,
    node: NodeIndex,
    material: &'static Material,
    /// A sound class called with `:force`, instead of the preset.
    class: Option<Expr>,
    /// The modes of its shape (`:modal`), instead of the preset.
    model: Option<Arc<Model>>,
    /// The preset's modes and scale, when it has neither.
    preset: Preset,
}

impl Object {
    /// Seconds its sound rings after a blow: the longest T60 of its modes.
    fn ring(&self, nyquist: f64) -> f64 {
        match &self.model {
            Some(model) => model
                .modes
                .iter()
                .filter(|m| m.damped_frequency() <= 0.9 * nyquist)
                .map(|m| 3.0 * std::f64::consts::LN_10 / m.decay())
                .fold(0.0, f64::max),
            None => self.preset.t60,
        }
    }
}

/// Modes of each object's shape with `:modal` and no `:modes`.
const CONTACT_MODES: usize = super::modal::DEFAULT_MODES;
/// The most degrees of freedom of an object's analysis: a shot has several objects,
/// each solved in seconds (and cached); a `modal` node is the place for finer ones.
const CONTACT_MAX_DOFS: usize = 30_000;

/// A material's sound for a body of a given size: modes of a free solid box.
#[derive(Clone, Debug)]
pub(crate) struct Preset {
    /// (frequency Hz, bandwidth Hz, gain) of each mode.
    modes: Vec<(f64, f64, f64)>,
    /// The longest 60 dB decay, seconds.
    t60: f64,
}

/// The preset of `material` for a body whose box is `size` (m), of mass `mass` (kg)
/// and surface `area` (m²), heard at 1 m: the modes of a free box,
/// f = (c/2)·√((l/X)² + (m/Y)² + (n/Z)²) with c = √(E/ρ), the lowest
/// [`PRESET_MODES`] below `nyquist`, each with the material's bandwidth η·f (so its
/// T60 is 2.2/(η·f)), gain ∝ 1/k. A resonator of unit peak gain rings after an
/// impulse J at about 2π·η·f·J; scaled by 1/(η·m) that is the body's acceleration
/// ω·J/m, and a compact body of surface S radiates ρ₀·S·a/(4π) pascals at 1 m.
pub(crate) fn preset(
    material: &Material,
    size: DVec3,
    mass: f64,
    area: f64,
    nyquist: f64,
) -> Preset {
    let c = material.bar_speed();
    let size = size.max(DVec3::splat(1e-4));
    let mut freqs = Vec::new();
    for l in 0..16 {
        for m in 0..16 {
            for n in 0..16 {
                if l + m + n == 0 {
                    continue;
                }
                let k = DVec3::new(l as f64, m as f64, n as f64) / size;
                let f = 0.5 * c * k.length();
                if f < 0.9 * nyquist {
                    freqs.push(f);
                }
            }
        }
    }
    freqs.sort_by(f64::total_cmp);
    freqs.dedup_by(|a, b| (*a - *b).abs() < 0.005 * *b);
    freqs.truncate(PRESET_MODES);
    let weights: f64 = (1..=freqs.len()).map(|k| 1.0 / k as f64).sum();
    let scale = AIR_DENSITY * area
        / (4.0 * std::f64::consts::PI)
        / FULL_SCALE_PA
        / (material.loss * mass.max(1e-6));
    let modes: Vec<(f64, f64, f64)> = freqs
        .iter()
        .enumerate()
        .map(|(k, &f)| (f, material.loss * f, scale / ((k + 1) as f64 * weights)))
        .collect();
    let t60 = modes
        .iter()
        .map(|&(f, _, _)| material.t60(f))
        .fold(0.0, f64::max);
    Preset { modes, t60 }
}

impl Preset {
    /// `(combine (* gains (resonz force freqs bandwidths)))`.
    fn expr(&self, span: Span) -> Expr {
        let column = |k: fn(&(f64, f64, f64)) -> f64| self.modes.iter().map(k).collect::<Vec<_>>();
        resonator_bank(&column(|m| m.2), &column(|m| m.0), &column(|m| m.1), span)
    }
}

/// A constant track: keys at `times` (seconds of scene time), linear.
fn track(times: &[f64], values: &[f64]) -> Option<Arc<KeyframeTrack>> {
    KeyframeTrack::new(times.to_vec(), values.to_vec(), Interpolation::Linear)
        .ok()
        .map(Arc::new)
}

impl Lowerer<'_> {
    /// A `contacts` form: one instance per object per contact found.
    pub(crate) fn lower_contacts(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let bad = |l: &Self, message: String, span: Span, label: &str, help: &str| {
            l.diag("timbre::bad-contacts", message, origin)
                .label(span, label.to_owned())
                .help(help.to_owned())
        };
        let shot_name = items.get(1).and_then(Expr::as_symbol);
        let Some(file) = shot_name.and_then(|n| self.names.motions.iter().find(|m| m.name == n))
        else {
            let span = items.get(1).map_or(form.span, |e| e.span);
            let message = match shot_name {
                Some(name) => format!("no motion file is named `{name}`"),
                None => "`contacts` needs the name of a motion file".into(),
            };
            return Err(bad(
                self,
                message,
                span,
                "expected the name of a (motion …) form",
                &format!("read the shot first with (motion shot \"drop.glb\"), then write {USAGE}"),
            ));
        };
        let (shot, start, shot_name) = (file.shot.clone(), file.start, file.name.clone());
        let options = self.options(
            &items[2..],
            "contacts",
            &[
                "materials",
                "sounds",
                "masses",
                "gravity",
                "margin",
                "tolerance",
                "min-speed",
                "spacing",
                "suppress",
                "gain",
                "length",
                "frame-rate",
                "first-frame",
                "roughness",
                "grain",
                "modal",
                "modes",
            ],
            origin,
        )?;
        let Some(materials_expr) = options.get("materials") else {
            return Err(bad(
                self,
                "`contacts` needs `:materials`".into(),
                form.span,
                "no :materials",
                &format!("name each object's material: {USAGE}"),
            ));
        };
        let settings = self.contact_settings(&options, origin)?;
        let pairs = self.name_pairs(materials_expr, "materials", origin)?;
        let mut objects = self.contact_objects(&shot, &pairs, materials_expr, origin)?;
        if let Some(sounds) = options.get("sounds") {
            for (name, span, class) in self.name_pairs(sounds, "sounds", origin)? {
                let Some(object) = objects.iter_mut().find(|o| o.name == name) else {
                    return Err(bad(
                        self,
                        format!("\"{name}\" has a sound but no material"),
                        span,
                        "not in :materials",
                        "every object that sounds needs a material in :materials",
                    ));
                };
                let call = list(vec![class.clone()], class.span);
                self.instance_class(&call, USAGE, origin)?;
                object.class = Some(class.clone());
            }
        }
        let masses = match options.get("masses") {
            Some(e) => {
                let mut masses = vec![];
                for (name, _, value) in self.name_pairs(e, "masses", origin)? {
                    masses.push((name, self.constant_option(value, "a mass", origin)?));
                }
                masses
            }
            None => vec![],
        };
        let bodies: Vec<Body> = objects
            .iter()
            .map(|o| Body {
                name: o.name.clone(),
                node: o.node,
                density: o.material.density,
                mass: masses.iter().find(|(n, _)| *n == o.name).map(|(_, m)| *m),
            })
            .collect();
        let found = contacts::find_contacts(&shot, &bodies, &settings.search).map_err(|e| {
            let span = match (&e, options.get("masses")) {
                (ContactError::BadMass { .. }, Some(masses)) => masses.span,
                _ => materials_expr.span,
            };
            bad(
                self,
                e.to_string(),
                span,
                "in these objects",
                "give each object a closed mesh, and masses above 0",
            )
        })?;
        for warning in &found.warnings {
            let diag = self
                .diag("timbre::open-mesh", warning.clone(), origin)
                .label(materials_expr.span, "this object")
                .help("close the mesh (or accept its convex hull) for exact contacts");
            self.warn(diag);
        }
        let nyquist = 0.5 * self.settings.sample_rate.unwrap_or(48_000.0);
        for (object, report) in objects.iter_mut().zip(&found.bodies) {
            let (size, area) = (report.size, report.area);
            // An immovable object rings with the mass of its mesh (a sheet's as 1 cm
            // thick).
            let mass = if report.mass.is_finite() {
                report.mass
            } else if report.volume > 0.0 {
                report.volume * object.material.density
            } else {
                area * 0.01 * object.material.density
            };
            object.preset = preset(object.material, size, mass, area, nyquist);
        }
        if let Some(modal) = options.get("modal") {
            let modes = match options.get("modes") {
                Some(e) => {
                    let count = self.constant_option(e, "a number of modes", origin)?;
                    if !(count >= 1.0 && count.fract() == 0.0 && count <= 10_000.0) {
                        return Err(bad(
                            self,
                            format!("`:modes` is {count}; it counts modes: a whole number from 1"),
                            e.span,
                            "modes",
                            "write e.g. :modes 32",
                        ));
                    }
                    count as usize
                }
                None => CONTACT_MODES,
            };
            for (index, span) in self.modal_objects(modal, &objects, origin)? {
                let model = self.object_model(&shot, &objects[index], modes, span, origin)?;
                objects[index].model = Some(model);
            }
        } else if let Some(e) = options.get("modes") {
            return Err(bad(
                self,
                "`:modes` counts the modes of the objects `:modal` names".into(),
                e.span,
                "without :modal",
                "name the objects that ring with the modes of their shapes: :modal (\"Cube\")",
            ));
        }
        let form = Sounding {
            shot: &shot,
            name: &shot_name,
            start,
            settings: &settings,
            suppressed: self.suppressed(options.get("suppress"), origin)?,
            nyquist,
            span: form.span,
            origin,
        };
        let mut rows = Vec::new();
        let mut made = self.sound_impacts(&form, &found, &objects, &mut rows)?;
        made += self.sound_sustained(&form, &found, &objects, &mut rows)?;
        rows.sort_by(|x, y| x.time.total_cmp(&y.time));
        let shapes = objects
            .iter()
            .filter_map(|o| Some((o.name.clone(), o.model.clone()?)))
            .collect();
        self.scene.found_contacts.push(FoundContacts {
            shot: shot_name.clone(),
            frame_rate: settings.frame_rate,
            first_frame: settings.first_frame,
            rows,
            instances: made,
            shapes,
        });
        Ok(())
    }
}

/// The form's search tolerances and sound settings.
struct Settings {
    search: ContactOptions,
    gain: Option<f64>,
    /// Seconds each impact's sound lasts (default: its preset's longest T60).
    length: Option<f64>,
    frame_rate: f64,
    /// The frame at scene time 0, for the frames shown.
    first_frame: f64,
    /// The surfaces' rms roughness and shortest wavelength (m), for `scrape` and
    /// `roll` ([`DEFAULT_ROUGHNESS`], and their default grain, when not given).
    roughness: Option<f64>,
    grain: Option<f64>,
}

/// What the instances of one `contacts` form share.
struct Sounding<'f> {
    shot: &'f Arc<Shot>,
    /// The motion file's name, first in every instance's name.
    name: &'f str,
    /// Scene time of the shot's time 0.
    start: f64,
    settings: &'f Settings,
    /// `:suppress`: pairs, and the span of scene time they are silent in.
    suppressed: Vec<(String, String, f64, f64)>,
    /// Half the scene's sample rate, Hz.
    nyquist: f64,
    span: Span,
    origin: &'f Origin,
}

impl Sounding<'_> {
    /// Where an object with modes is struck at shot time `t`: `local`, a point of
    /// its unscaled mesh (as contacts give it), in the scaled mesh its model was
    /// made of; along `push`, the world direction of the force on it, turned into
    /// its own frame. `None` for an object without modes.
    fn strike(&self, object: &Object, local: DVec3, push: DVec3, t: f64) -> Option<Strike> {
        object.model.as_ref()?;
        let scale = self.shot.pose(object.node, 0.0).scale;
        let rotation = self.shot.pose(object.node, t).rotation;
        Some(Strike {
            point: (local * scale).to_array(),
            direction: (rotation.inverse() * push).to_array(),
        })
    }

    /// Where an object with modes is struck at each key of a sustained contact, on
    /// its `side`: the contact's point on it and the force's direction, as
    /// [`Self::strike`] puts an impact's, at the times of the force's tracks
    /// ([`sustained_times`]). `None` for an object without modes.
    fn strikes_along(
        &self,
        object: &Object,
        samples: &[ContactSample],
        side: Side,
    ) -> Option<Struck> {
        let strike = |s: &ContactSample| match side {
            Side::A => self.strike(object, s.point_a, -s.normal, s.time),
            Side::B => self.strike(object, s.point_b, s.normal, s.time),
        };
        let mut strikes = vec![strike(samples.first()?)?];
        for s in samples {
            strikes.push(strike(s)?);
        }
        strikes.push(strike(samples.last()?)?);
        Some(Struck::Along(sustained_times(samples, self.start), strikes))
    }

    /// Whether a contact of `a` and `b` at shot time `t` sounds.
    fn keeps(&self, t: f64, a: &str, b: &str) -> bool {
        let t = t + self.start;
        !self.suppressed.iter().any(|(x, y, from, until)| {
            ((x == a && y == b) || (x == b && y == a)) && (*from..=*until).contains(&t)
        })
    }
}

/// Which body of a contact an object is: a or b.
#[derive(Clone, Copy)]
enum Side {
    A,
    B,
}

/// Where an object with modes is struck.
#[derive(Clone)]
enum Struck {
    /// Once, at one point: an impact.
    Once(Strike),
    /// Where a sustained contact is at each of its keys (scene seconds).
    Along(Vec<f64>, Vec<Strike>),
}

/// The keys of a sustained contact's tracks, in scene seconds (`start` is the
/// shot's): each sample's time, and [`RAMP`] before the first and after the last.
fn sustained_times(samples: &[ContactSample], start: f64) -> Vec<f64> {
    let mut times = vec![samples[0].time + start - RAMP];
    times.extend(samples.iter().map(|s| s.time + start));
    times.push(samples[samples.len() - 1].time + start + RAMP);
    times
}

/// One instance of a contact: its name and stem kind, the force that drives it, when
/// and where.
struct ContactSound {
    name: String,
    kind: &'static str,
    force: NodeId,
    /// Where an object with modes is struck.
    strike: Option<Struck>,
    start: f64,
    length: f64,
    place: Path,
}

/// What a sustained contact's force on one object is read from.
#[derive(Clone, Copy)]
struct Surface<'o> {
    kind: ContactKind,
    object: &'o Object,
    other: &'o Object,
    /// The object's local radius of curvature at the contact, m.
    radius: f64,
    seed: f64,
}

/// The Hertz force of an impact as a call of `impact` scaled to the impulse found,
/// and its peak in newtons. The movable (or lighter) body is body a of the call: the
/// force is the same on both.
fn impact_force(
    a: &Object,
    b: &Object,
    impact: &Impact,
    found: &Contacts,
    span: Span,
) -> (Expr, f64) {
    let (mass_a, mass_b) = (found.bodies[impact.a].mass, found.bodies[impact.b].mass);
    let (first, second, r1, r2, m1, m2) = if mass_a <= mass_b {
        (a, b, impact.radius_a, impact.radius_b, mass_a, mass_b)
    } else {
        (b, a, impact.radius_b, impact.radius_a, mass_b, mass_a)
    };
    let mut call = vec![
        symbol("impact", span),
        keyword("a", span),
        symbol(first.material.name, span),
        keyword("b", span),
        symbol(second.material.name, span),
        keyword("radius", span),
        number(r1, span),
        keyword("mass", span),
        number(m1, span),
        keyword("speed", span),
        number(impact.normal_speed, span),
    ];
    if r2.is_finite() {
        call.extend([keyword("radius-b", span), number(r2, span)]);
    }
    if m2.is_finite() {
        call.extend([keyword("mass-b", span), number(m2, span)]);
    }
    // The pulse `impact` makes (`dsp::impact`), for its peak and the impulse it
    // carries: 2·m*·v, as an elastic contact does. Scaled to the impulse the motion
    // shows, (1 + e)·m*·v, it carries what the bodies exchanged.
    let pulse = HertzBodies {
        youngs_a: first.material.youngs,
        poisson_a: first.material.poisson,
        youngs_b: second.material.youngs,
        poisson_b: second.material.poisson,
        radius_a: r1,
        radius_b: r2,
        mass_a: m1,
        mass_b: m2,
        speed: impact.normal_speed,
    }
    .impact();
    let (peak, elastic) = pulse.map_or((0.0, 0.0), |p| (p.peak_force(), p.impulse()));
    let share = if elastic > 0.0 {
        (impact.impulse / elastic).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let force = if impact.impulse > 0.0 && elastic > 0.0 {
        list(
            vec![symbol("*", span), number(share, span), list(call, span)],
            span,
        )
    } else {
        list(call, span)
    };
    (force, share * peak)
}

/// The runs of one kind (slide or roll) of a sustained contact's keys.
fn kind_runs(samples: &[ContactSample]) -> Vec<(ContactKind, &[ContactSample])> {
    let mut runs = vec![];
    let mut start = 0;
    for k in 1..=samples.len() {
        if k == samples.len() || samples[k].kind != samples[start].kind {
            if samples[start].kind != ContactKind::Rest && k - start >= 2 {
                runs.push((samples[start].kind, &samples[start..k]));
            }
            start = k;
        }
    }
    runs
}

fn sustained_row(
    kind: ContactKind,
    run: &[ContactSample],
    a: &str,
    b: &str,
    start: f64,
) -> ContactRow {
    let mean = |f: fn(&ContactSample) -> f64| run.iter().map(f).sum::<f64>() / run.len() as f64;
    ContactRow {
        time: run[0].time + start,
        kind: kind.name(),
        a: a.to_owned(),
        b: b.to_owned(),
        normal_speed: 0.0,
        slip_speed: mean(|s| s.slip_speed),
        rolling_speed: mean(|s| s.rolling_speed),
        impulse: 0.0,
        force: mean(|s| s.normal_force),
        point: run[0].point,
        length: run[run.len() - 1].time - run[0].time,
    }
}

impl Lowerer<'_> {
    fn contact_settings(
        &mut self,
        options: &Options<'_>,
        origin: &Origin,
    ) -> Result<Settings, Diag> {
        let mut search = ContactOptions::default();
        let number = |l: &mut Self, key: &str, what: &str, min: f64| -> Result<Option<f64>, Diag> {
            let Some(e) = options.get(key) else {
                return Ok(None);
            };
            let value = l.constant_option(e, what, origin)?;
            if !(value.is_finite() && value >= min) {
                return Err(l
                    .diag(
                        "timbre::bad-contacts",
                        format!("`:{key}` is {value}; {what} is a finite number of at least {min}"),
                        origin,
                    )
                    .label(e.span, key.to_owned())
                    .help(format!("see `{USAGE}` in the language's motion page")));
            }
            Ok(Some(value))
        };
        if let Some(v) = number(self, "margin", "the gap at which objects touch (m)", 0.0)? {
            search.margin = v;
        }
        if let Some(v) = number(self, "tolerance", "the touching distance (m)", 0.0)? {
            search.tolerance = v;
        }
        if let Some(v) = number(self, "min-speed", "the slowest impact (m/s)", 0.0)? {
            search.min_speed = v;
        }
        if let Some(v) = number(self, "spacing", "the least time between impacts (s)", 0.0)? {
            search.spacing = v;
        }
        let gain = number(self, "gain", "a gain", 0.0)?;
        let roughness = number(self, "roughness", "a surface's rms roughness (m)", 0.0)?;
        let grain = number(self, "grain", "a surface's shortest wavelength (m)", 1e-9)?;
        let length = number(self, "length", "how long each impact sounds (s)", 1e-3)?;
        let frame_rate =
            number(self, "frame-rate", "frames per second", 1e-3)?.unwrap_or(DEFAULT_FRAME_RATE);
        let first_frame = number(self, "first-frame", "the frame at time 0", -1e9)?.unwrap_or(0.0);
        if let Some(e) = options.get("gravity") {
            let value = self.lower(e, origin, &mut Scope::new())?;
            match self.graph.const_value(value) {
                Some(&[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => {
                    search.gravity = DVec3::new(x, y, z)
                }
                _ => {
                    return Err(self
                        .diag(
                            "timbre::bad-contacts",
                            "`:gravity` is a constant vector of three numbers",
                            origin,
                        )
                        .label(e.span, "gravity")
                        .help("write :gravity (vector 0 0 -9.81) (Z is up, m/s²)"))
                }
            }
        }
        Ok(Settings {
            search,
            gain,
            length,
            frame_rate,
            first_frame,
            roughness,
            grain,
        })
    }

    /// A list of `("Name" value)` pairs.
    fn name_pairs<'e>(
        &self,
        e: &'e Expr,
        key: &str,
        origin: &Origin,
    ) -> Result<Vec<(String, Span, &'e Expr)>, Diag> {
        let bad = |span: Span| {
            self.diag(
                "timbre::bad-contacts",
                format!("`:{key}` is a list of (\"Object\" value) pairs"),
                origin,
            )
            .label(span, "expected (\"Name\" value)")
            .help(format!("write {USAGE}"))
        };
        let items = e.as_list().ok_or_else(|| bad(e.span))?;
        items
            .iter()
            .map(|pair| match pair.as_list() {
                Some([name, value]) => match &name.kind {
                    ExprKind::Str(n) => Ok((n.clone(), name.span, value)),
                    _ => Err(bad(name.span)),
                },
                _ => Err(bad(pair.span)),
            })
            .collect()
    }

    /// The objects `:materials` names: glTF nodes by name, or every node whose mesh
    /// has a glTF material of that name.
    fn contact_objects(
        &self,
        shot: &Shot,
        pairs: &[(String, Span, &Expr)],
        materials_expr: &Expr,
        origin: &Origin,
    ) -> Result<Vec<Object>, Diag> {
        let mut objects: Vec<Object> = vec![];
        for (name, span, value) in pairs {
            let material = crate::catalogue::physical::named_material(self, value, origin)?;
            let mut nodes: Vec<(String, NodeIndex)> = match shot.node(name) {
                Some(node) => vec![(name.clone(), node)],
                None => shot
                    .node_names()
                    .filter_map(|n| shot.node(n).map(|i| (n.to_owned(), i)))
                    .filter(|(_, i)| {
                        shot.mesh(*i)
                            .is_some_and(|m| m.materials.iter().any(|m| m == name))
                    })
                    .collect(),
            };
            if nodes.is_empty() {
                let help = match super::did_you_mean(name, shot.node_names()) {
                    Some(close) => format!("did you mean \"{close}\"?"),
                    None => "name a node of the shot, or a material of its meshes".into(),
                };
                return Err(self
                    .diag(
                        "timbre::unknown-node",
                        format!("the shot has no node or material \"{name}\""),
                        origin,
                    )
                    .label(*span, "not in the shot")
                    .help(help));
            }
            for (node_name, node) in nodes.drain(..) {
                if shot.mesh(node).is_none() {
                    return Err(self
                        .diag(
                            "timbre::bad-contacts",
                            format!("node \"{node_name}\" has no mesh"),
                            origin,
                        )
                        .label(*span, "no mesh to touch with")
                        .help("name objects with meshes; a camera or an empty cannot touch"));
                }
                if objects.iter().any(|o| o.node == node) {
                    continue;
                }
                objects.push(Object {
                    name: node_name,
                    node,
                    material,
                    class: None,
                    model: None,
                    preset: Preset {
                        modes: vec![],
                        t60: 0.0,
                    },
                });
            }
        }
        if objects.len() < 2 {
            return Err(self
                .diag(
                    "timbre::bad-contacts",
                    "contacts need at least two objects",
                    origin,
                )
                .label(materials_expr.span, format!("{} object", objects.len()))
                .help(format!("name every object that touches: {USAGE}")));
        }
        Ok(objects)
    }

    /// `:suppress (("A" "B") ("A" "B" from until) …)`: no contact of that pair (in
    /// that span of scene time).
    fn suppressed(
        &mut self,
        e: Option<&Expr>,
        origin: &Origin,
    ) -> Result<Vec<(String, String, f64, f64)>, Diag> {
        let Some(e) = e else {
            return Ok(vec![]);
        };
        let bad = |l: &Self, span: Span| {
            l.diag("timbre::bad-contacts", "`:suppress` is a list of (\"A\" \"B\") or (\"A\" \"B\" from until)", origin)
                .label(span, "here")
                .help("write :suppress ((\"Cube\" \"Floor\" 1.2 1.5)) to silence a pair from 1.2 s to 1.5 s")
        };
        let mut out = vec![];
        for item in e.as_list().ok_or_else(|| bad(self, e.span))? {
            let parts = item.as_list().ok_or_else(|| bad(self, item.span))?;
            let name = |x: &Expr| match &x.kind {
                ExprKind::Str(s) => Some(s.clone()),
                _ => None,
            };
            let (Some(a), Some(b)) = (parts.first().and_then(name), parts.get(1).and_then(name))
            else {
                return Err(bad(self, item.span));
            };
            let (from, until) = match &parts[2..] {
                [] => (f64::NEG_INFINITY, f64::INFINITY),
                [from, until] => (
                    self.constant_option(from, "a time", origin)?,
                    self.constant_option(until, "a time", origin)?,
                ),
                _ => return Err(bad(self, item.span)),
            };
            out.push((a, b, from, until));
        }
        Ok(out)
    }

    /// The force of a sustained contact on one object while it is of `kind`: `scrape`
    /// at the slip speed while it slides, `roll` at the rolling speed while it rolls,
    /// scaled by the normal force while it is of that kind and by 0 otherwise. Both
    /// are tracks that move linearly between keys, and rise from and fall back to 0
    /// over [`RAMP`] at the ends, so the force of one kind fades as the other's rises,
    /// without a click. `None` if it is never of that kind.
    fn sustained_force(
        &mut self,
        form: &Sounding<'_>,
        samples: &[ContactSample],
        surface: &Surface<'_>,
    ) -> Result<Option<NodeId>, Diag> {
        let Surface {
            kind,
            object,
            other,
            radius,
            seed,
        } = *surface;
        let (start, span, origin) = (form.start, form.span, form.origin);
        if !samples.iter().any(|s| s.kind == kind) {
            return Ok(None);
        }
        let times = sustained_times(samples, start);
        let values = |f: &dyn Fn(&ContactSample) -> f64| {
            let mut v = vec![0.0];
            v.extend(samples.iter().map(f));
            v.push(0.0);
            v
        };
        let speed = track(
            &times,
            &values(&|s| match kind {
                ContactKind::Roll => s.rolling_speed,
                _ => s.slip_speed,
            }),
        );
        let load = track(
            &times,
            &values(&|s| if s.kind == kind { s.normal_force } else { 0.0 }),
        );
        let (Some(speed), Some(load)) = (speed, load) else {
            return Ok(None);
        };
        // The tracks read scene time in an instance that starts at the first key.
        self.time_offset = times[0];
        let speed = self.keyframe_node(speed);
        let load = self.keyframe_node(load);
        let mut scope: Scope = vec![("speed".to_owned(), speed), ("load".to_owned(), load)];
        let mut call = vec![
            symbol(
                if kind == ContactKind::Roll {
                    "roll"
                } else {
                    "scrape"
                },
                span,
            ),
            symbol("speed", span),
            symbol("load", span),
            keyword("seed", span),
            number(seed, span),
        ];
        let roughness = form.settings.roughness.unwrap_or(DEFAULT_ROUGHNESS);
        call.extend([keyword("roughness", span), number(roughness, span)]);
        if let Some(grain) = form.settings.grain {
            call.extend([keyword("grain", span), number(grain, span)]);
        }
        if kind == ContactKind::Roll {
            call.extend([
                keyword("radius", span),
                number(radius, span),
                keyword("a", span),
                symbol(object.material.name, span),
                keyword("b", span),
                symbol(other.material.name, span),
            ]);
        }
        self.time_offset = times[0];
        let node = self.lower(&list(call, span), origin, &mut scope);
        self.time_offset = 0.0;
        node.map(Some)
    }

    /// An instance per object of each impact (heard from its world point), and its
    /// row of the score; how many instances.
    fn sound_impacts(
        &mut self,
        form: &Sounding<'_>,
        found: &Contacts,
        objects: &[Object],
        rows: &mut Vec<ContactRow>,
    ) -> Result<usize, Diag> {
        let mut made = 0;
        for (k, impact) in found.impacts.iter().enumerate() {
            let (a, b) = (&objects[impact.a], &objects[impact.b]);
            if !form.keeps(impact.time, &a.name, &b.name) {
                continue;
            }
            let time = impact.time + form.start;
            let (force_expr, peak) = impact_force(a, b, impact, found, form.span);
            rows.push(ContactRow {
                time,
                kind: "impact",
                a: a.name.clone(),
                b: b.name.clone(),
                normal_speed: impact.normal_speed,
                slip_speed: impact.tangential_speed,
                rolling_speed: 0.0,
                impulse: impact.impulse,
                force: peak,
                point: impact.point,
                length: 0.0,
            });
            // The normal points from a toward b: b pushes a back along −normal.
            for (object, local, push) in [
                (a, impact.point_a, -impact.normal),
                (b, impact.point_b, impact.normal),
            ] {
                self.time_offset = time;
                let force = self.lower(&force_expr, form.origin, &mut Scope::new());
                self.time_offset = 0.0;
                let ring = object.ring(form.nyquist).clamp(0.05, 6.0);
                let sound = ContactSound {
                    name: format!("{}.impact-{k}.{}", form.name, object.name),
                    kind: "impacts",
                    force: force?,
                    strike: form
                        .strike(object, local, push, impact.time)
                        .map(Struck::Once),
                    start: time,
                    length: form.settings.length.unwrap_or(ring),
                    place: Path::Fixed(impact.point),
                };
                made += usize::from(self.add_contact_instance(form, object, sound)?);
            }
        }
        Ok(made)
    }

    /// Instances per object of each sustained contact that slides or rolls (heard
    /// from the object's origin), and a row of the score per run of one kind; how
    /// many instances.
    fn sound_sustained(
        &mut self,
        form: &Sounding<'_>,
        found: &Contacts,
        objects: &[Object],
        rows: &mut Vec<ContactRow>,
    ) -> Result<usize, Diag> {
        let mut made = 0;
        for (k, contact) in found.sustained.iter().enumerate() {
            let (a, b) = (&objects[contact.a], &objects[contact.b]);
            let samples = &contact.samples;
            if !form.keeps(samples[0].time, &a.name, &b.name) {
                continue;
            }
            for (kind, run) in kind_runs(samples) {
                rows.push(sustained_row(kind, run, &a.name, &b.name, form.start));
            }
            let from = samples[0].time + form.start - RAMP;
            let until = samples[samples.len() - 1].time + form.start + RAMP;
            // The normal points from a toward b: b pushes a back along −normal.
            let first = &samples[0];
            for (object, other, radius, side) in [
                (a, b, first.radius_a, Side::A),
                (b, a, first.radius_b, Side::B),
            ] {
                let struck = form.strikes_along(object, samples, side);
                for (kind, stem) in [
                    (ContactKind::Slide, "sliding"),
                    (ContactKind::Roll, "rolling"),
                ] {
                    // A surface per pair of objects, the same for both of them.
                    let seed = (k * 2 + usize::from(kind == ContactKind::Roll)) as f64 + 1.0;
                    let surface = Surface {
                        kind,
                        object,
                        other,
                        radius,
                        seed,
                    };
                    let Some(force) = self.sustained_force(form, samples, &surface)? else {
                        continue;
                    };
                    let sound = ContactSound {
                        name: format!("{}.{stem}-{k}.{}", form.name, object.name),
                        kind: stem,
                        force,
                        strike: struck.clone(),
                        start: from,
                        length: until - from + object.ring(form.nyquist).clamp(0.05, 2.0),
                        place: Path::Moving(
                            NodeRef {
                                shot: form.shot.clone(),
                                node: object.node,
                                start: form.start,
                                name: object.name.clone(),
                            }
                            .position(),
                        ),
                    };
                    made += usize::from(self.add_contact_instance(form, object, sound)?);
                }
            }
        }
        Ok(made)
    }

    /// Adds the instance of one object's sound driven by a force, heard at its place
    /// (or at the channels as written when the scene has no listener); false when it
    /// is silent (every mode of its shape above the sample rate's reach).
    fn add_contact_instance(
        &mut self,
        form: &Sounding<'_>,
        object: &Object,
        sound: ContactSound,
    ) -> Result<bool, Diag> {
        let ContactSound {
            name,
            kind,
            force,
            strike,
            start,
            length,
            place,
        } = sound;
        let (span, origin) = (form.span, form.origin);
        let mut scope: Scope = vec![("force".to_owned(), force)];
        // Keyframes of the sound (a moving strike's gains) read scene time.
        self.time_offset = start;
        let call = match (&object.class, &object.model, strike) {
            (Some(class), _, _) => Some(list(
                vec![class.clone(), keyword("force", span), symbol("force", span)],
                span,
            )),
            (None, Some(model), Some(Struck::Once(strike))) => {
                self.driven_model(model, &strike, 1.0, span)
            }
            (None, Some(model), Some(Struck::Along(times, strikes))) => self
                .moving_driven_model(model, &times, &strikes, 1.0, span)
                .map(|(tree, names)| {
                    scope.extend(names);
                    tree
                }),
            // A body so small that all its modes are above the sample rate's reach.
            _ => (!object.preset.modes.is_empty()).then(|| object.preset.expr(span)),
        };
        let Some(call) = call else {
            self.time_offset = 0.0;
            return Ok(false);
        };
        let sound = self.lower(&call, origin, &mut scope);
        self.time_offset = 0.0;
        let mut sound = sound?;
        if let Some(gain) = form.settings.gain {
            let gain = self.graph.constant(gain);
            sound = self
                .graph
                .add(Op::Binary(timbre_ir::op::BinaryOp::Mul), vec![gain, sound]);
        }
        let class = object
            .class
            .as_ref()
            .and_then(Expr::as_symbol)
            .unwrap_or(object.material.name);
        // The force starts from rest: no ramp of its own.
        let timing = Timing {
            start,
            stop: Some(start + length),
            fade_in: FadeIn::Always(0.0),
        };
        let place = self.scene.space.has_receivers().then_some((place, span));
        let names = Names {
            name: &name,
            class,
            stem: Stem {
                object: Some(object.name.as_str().into()),
                kind: Some(kind.into()),
            },
        };
        let instance =
            self.finish_instance(names, sound, timing, place, &Options::none(), origin)?;
        self.scene.instances.push(instance);
        Ok(true)
    }

    /// The objects `:modal` names, as indices into `objects`, with the span of each
    /// name.
    fn modal_objects(
        &self,
        e: &Expr,
        objects: &[Object],
        origin: &Origin,
    ) -> Result<Vec<(usize, Span)>, Diag> {
        let items = e.as_list().unwrap_or_default();
        if items.is_empty() {
            return Err(self
                .diag(
                    "timbre::bad-contacts",
                    "`:modal` is a list of the objects that ring with their shapes' modes",
                    origin,
                )
                .label(e.span, "expected (\"Name\" …)")
                .help("write :modal (\"Cube\"): each object named in :materials"));
        }
        let mut chosen = vec![];
        for item in items {
            let ExprKind::Str(name) = &item.kind else {
                return Err(self
                    .diag(
                        "timbre::bad-contacts",
                        format!(
                            "an object of `:modal` is named by a string, not {}",
                            item.describe()
                        ),
                        origin,
                    )
                    .label(item.span, "expected \"Name\"")
                    .help("write :modal (\"Cube\"): each object named in :materials"));
            };
            let Some(index) = objects.iter().position(|o| o.name == *name) else {
                let help = match super::did_you_mean(name, objects.iter().map(|o| o.name.as_str()))
                {
                    Some(close) => format!("did you mean \"{close}\"?"),
                    None => "name objects of :materials".into(),
                };
                return Err(self
                    .diag(
                        "timbre::bad-contacts",
                        format!("\"{name}\" is not an object of :materials"),
                        origin,
                    )
                    .label(item.span, "no material")
                    .help(help));
            };
            if objects[index].class.is_some() {
                return Err(self
                    .diag(
                        "timbre::bad-contacts",
                        format!("\"{name}\" has a class of :sounds and the modes of its shape"),
                        origin,
                    )
                    .label(item.span, "modes here")
                    .help("an object sounds one way: drop it from :sounds or from :modal"));
            }
            chosen.push((index, item.span));
        }
        Ok(chosen)
    }

    /// The modes of an object's mesh, scaled as its node is at time 0, in its own
    /// frame, of its material (`timbre_modal`, through its cache).
    fn object_model(
        &mut self,
        shot: &Shot,
        object: &Object,
        modes: usize,
        span: Span,
        origin: &Origin,
    ) -> Result<Arc<Model>, Diag> {
        let scale = shot.pose(object.node, 0.0).scale;
        // `contact_objects` keeps only nodes with meshes: an empty one holds no solid.
        let shape = Shape::Mesh(shot_mesh(shot, object.node).unwrap_or_default());
        let material = catalogue_material(object.material);
        let settings = ModalSettings {
            modes,
            resolution: Resolution {
                voxel: None,
                max_dofs: CONTACT_MAX_DOFS.min(self.options.limits.modal_dofs),
            },
        };
        let key = format!(
            "shot {:x} node {} × {scale:?} {material:?} {settings:?}",
            shot.content_hash(),
            object.name
        );
        match self.shared_model(key, &shape, &material, &settings, span, origin)? {
            Ok(model) => {
                self.modal_warnings(&model, span, origin);
                Ok(model)
            }
            Err(error) => Err(self
                .diag(
                    modal_code(&error),
                    format!("cannot find the modes of \"{}\": {error}", object.name),
                    origin,
                )
                .label(span, "this object")
                .help(
                    "the modes of a shape need a mesh that encloses a solid (a floor of one \
                     sheet has none: leave it to its material's preset); ask for fewer :modes \
                     if the solve fails",
                )),
        }
    }
}
