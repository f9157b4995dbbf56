//! Contacts in shots that Blender simulated itself (rigid bodies, baked, exported to
//! glTF by `examples/shots/make-contacts.py`), against a reference derived from the
//! same motion independently (`examples/shots/contact_reference.py`: one-sided
//! parabola fits of each free flight, carried to the first touch of analytic floor
//! and step planes). `.ci/run` makes the shots afresh and points
//! `TIMBRE_BLENDER_SHOT` at them; without it the committed copies are read.

use serde_json::Value;
use timbre_motion::contacts::{find_contacts, Body, ContactKind, ContactOptions, Contacts};
use timbre_motion::{Shot, ShotOptions};
use timbre_testkit::blender_contact_shot;

/// The shot's contacts, every object of the reference taking part, with Blender's
/// masses and gravity.
fn contacts(name: &str) -> (Contacts, Value) {
    let (glb, json) = blender_contact_shot(name);
    let bytes = std::fs::read(&glb).unwrap_or_else(|e| panic!("{}: {e}", glb.display()));
    let shot = Shot::read(
        &bytes,
        &mut |uri| Err(uri.to_string()),
        &ShotOptions::default(),
    )
    .unwrap();
    let reference: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let bodies: Vec<Body> = reference["objects"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(name, object)| Body {
            name: name.clone(),
            node: shot.node(name).unwrap_or_else(|| panic!("no node {name}")),
            density: 1000.0,
            mass: object["mass"].as_f64(),
        })
        .collect();
    let g = &reference["gravity"];
    let options = ContactOptions {
        gravity: glam::DVec3::new(
            g[0].as_f64().unwrap(),
            g[1].as_f64().unwrap(),
            g[2].as_f64().unwrap(),
        ),
        ..ContactOptions::default()
    };
    (find_contacts(&shot, &bodies, &options).unwrap(), reference)
}

fn names(found: &Contacts, a: usize, b: usize) -> (&str, &str) {
    (&found.bodies[a].name, &found.bodies[b].name)
}

/// Every fitted impact of the reference is found within 1 ms with its normal speed
/// within 5 %, and no impact is found while a body of it rests.
fn check_impacts(shot: &str) -> (Contacts, Value) {
    let (found, reference) = contacts(shot);
    let expected = reference["contacts_reference"]["impacts"]
        .as_array()
        .unwrap();
    for want in expected
        .iter()
        .filter(|i| i["fitted"].as_bool() != Some(false))
    {
        let time = want["time"].as_f64().unwrap();
        let speed = want["normal_speed_before"].as_f64().unwrap();
        let pair = (want["a"].as_str().unwrap(), want["b"].as_str().unwrap());
        let got = found
            .impacts
            .iter()
            .filter(|i| {
                let (a, b) = names(&found, i.a, i.b);
                (a, b) == pair || (b, a) == pair
            })
            .min_by(|x, y| (x.time - time).abs().total_cmp(&(y.time - time).abs()))
            .unwrap_or_else(|| panic!("{shot}: no impact of {pair:?}"));
        assert!(
            (got.time - time).abs() < 1e-3,
            "{shot}: {pair:?} at {time} s found at {} s",
            got.time
        );
        assert!(
            (got.normal_speed - speed).abs() < 0.05 * speed,
            "{shot}: {pair:?} at {time} s: normal speed {} m/s, reference {speed} m/s",
            got.normal_speed
        );
    }
    let rests = reference["contacts_reference"]["rest"].as_object().unwrap();
    for impact in &found.impacts {
        let (a, b) = names(&found, impact.a, impact.b);
        for body in [a, b] {
            for rest in rests
                .get(body)
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
            {
                let t = &rest["times"];
                let (from, until) = (t[0].as_f64().unwrap(), t[1].as_f64().unwrap());
                assert!(
                    !(from..=until).contains(&impact.time),
                    "{shot}: an impact of {a} and {b} at {} s while {body} rests ({from}–{until} s)",
                    impact.time
                );
            }
        }
    }
    (found, reference)
}

#[test]
fn a_cube_dropped_on_a_floor() {
    let (found, _) = check_impacts("cube-drop");
    assert!(!found.impacts.is_empty());
}

#[test]
fn a_ball_bouncing_down_stairs() {
    let (found, reference) = check_impacts("stairs");
    let expected = reference["contacts_reference"]["impacts"]
        .as_array()
        .unwrap()
        .len();
    assert!(found.impacts.len() >= expected, "{:#?}", found.impacts);
}

#[test]
fn a_line_of_dominoes_gives_one_impact_per_domino_in_order() {
    let (found, reference) = check_impacts("dominoes");
    let expected = reference["contacts_reference"]["impacts"]
        .as_array()
        .unwrap();
    let mut last = 0.0;
    for want in expected {
        let pair = (want["a"].as_str().unwrap(), want["b"].as_str().unwrap());
        let hits: Vec<_> = found
            .impacts
            .iter()
            .filter(|i| names(&found, i.a, i.b) == pair)
            .collect();
        assert_eq!(hits.len(), 1, "{pair:?}: {hits:#?}");
        let time = hits[0].time;
        assert!(
            time > last,
            "{pair:?} at {time} s, before the one before it"
        );
        let bracket = &want["frames_bracket"];
        let fps = reference["fps"].as_f64().unwrap();
        let (from, until) = (
            bracket[0].as_f64().unwrap() / fps,
            bracket[1].as_f64().unwrap() / fps,
        );
        assert!(
            (from - 1e-3..=until + 1e-3).contains(&time),
            "{pair:?} at {time} s, outside frames {bracket}"
        );
        last = time;
    }
}

#[test]
fn a_can_lands_slides_then_rolls() {
    let (found, reference) = check_impacts("can");
    let intervals = reference["contacts_reference"]["contacts"]
        .as_array()
        .unwrap();
    let samples: Vec<_> = found.sustained.iter().flat_map(|s| &s.samples).collect();
    for interval in intervals {
        let kind = match interval["kind"].as_str().unwrap() {
            "slide" => ContactKind::Slide,
            "roll" => ContactKind::Roll,
            _ => continue,
        };
        let t = &interval["times"];
        let (from, until) = (t[0].as_f64().unwrap(), t[1].as_f64().unwrap());
        let inside: Vec<_> = samples
            .iter()
            .filter(|s| s.time > from + 0.05 && s.time < until - 0.05)
            .collect();
        let agree = inside.iter().filter(|s| s.kind == kind).count();
        assert!(
            !inside.is_empty() && agree * 10 >= inside.len() * 9,
            "{kind:?} from {from} to {until} s: {agree} of {} keys agree",
            inside.len()
        );
    }
}
