//! The `contacts` form: a Blender shot's contacts made into instances, the decay its
//! presets promise, and its diagnostics at the form.

mod common;

use std::path::Path;

use timbre_ir::dsp::materials::OAK;
use timbre_ir::{Diagnostics, SourceFile};
use timbre_lang::{compile, CompileOptions, Compiled, Registry, SandboxLoader};

fn cube_drop() -> Vec<u8> {
    let shot = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/shots/cube-drop.glb");
    std::fs::read(shot).unwrap()
}

fn compile_shot(text: &str) -> Result<Compiled, Diagnostics> {
    compile_with_shot(text, &cube_drop())
}

fn compile_with_shot(text: &str, glb: &[u8]) -> Result<Compiled, Diagnostics> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("drop.glb"), glb).unwrap();
    let sandbox = SandboxLoader::new([dir.path()]).unwrap();
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &sandbox);
    let source = SourceFile::new(dir.path().join("scene.tt").display().to_string(), text);
    compile(source, Some(dir.path()), &options)
}

const HEAD: &str = "(scene :sample-rate 48000 :sync picture)\n(motion shot \"drop.glb\")\n(listener :object \"Camera\")\n";

/// The one error of `text`: code, message, underlined text, help.
fn error(text: &str) -> (String, String, String, String) {
    let Err(Diagnostics(diags)) = compile_shot(text) else {
        panic!("{text} compiled");
    };
    let diag = &diags[0];
    let span = diag.labels.first().map(|l| l.0).unwrap_or_default();
    (
        diag.code.to_string(),
        diag.message.clone(),
        text[span.start..span.end].to_owned(),
        diag.help.clone().unwrap_or_default(),
    )
}

#[test]
fn the_issue_s_scene_renders_as_written_one_instance_per_object_per_contact() {
    let text = format!("{HEAD}(contacts shot :materials ((\"Cube\" oak) (\"Floor\" concrete)))");
    let program = compile_shot(&text).unwrap_or_else(|e| panic!("{e:?}"));
    let found = &program.contacts[0];
    let impacts = found.rows.iter().filter(|r| r.kind == "impact").count();
    assert!(impacts >= 3, "{:#?}", found.rows);
    // Each impact sounds both objects, from the time it happens (picture sync
    // advances each by its delay to the camera, so none starts after it).
    let impact_instances: Vec<_> = program
        .instances
        .iter()
        .filter(|i| i.stem.kind.as_deref() == Some("impacts"))
        .collect();
    assert_eq!(impact_instances.len(), 2 * impacts);
    for row in found.rows.iter().filter(|r| r.kind == "impact") {
        let starts: Vec<f64> = impact_instances
            .iter()
            .filter(|i| (row.time - i.start) >= 0.0 && row.time - i.start < 0.02)
            .map(|i| i.start)
            .collect();
        assert_eq!(starts.len(), 2, "impact at {} s: {starts:?}", row.time);
    }
    assert_eq!(program.instances.len(), found.instances);
    let objects: Vec<_> = program
        .instances
        .iter()
        .filter_map(|i| i.stem.object.as_deref())
        .collect();
    assert!(objects.contains(&"Cube") && objects.contains(&"Floor"));
    // The score, as `timbre check --contacts` writes it.
    let tsv = timbre_lang::contact_score(&program.contacts);
    let header: Vec<&str> = tsv.lines().next().unwrap().split('\t').collect();
    for column in ["time", "kind", "a", "b", "normal-speed"] {
        assert!(header.contains(&column), "{header:?}");
    }
    assert_eq!(tsv.lines().count(), 1 + found.rows.len());
}

/// The score's frame column counts frames as `:frame-rate` and `:first-frame` say: a
/// shot whose scene time 0 is Blender's frame 1 (as the Blender extension writes it)
/// lists each impact on the frame Blender shows it, 1 + t × 24.
#[test]
fn the_score_counts_frames_from_the_first_frame() {
    let score = |options: &str| {
        let text = format!(
            "{HEAD}(contacts shot :materials ((\"Cube\" oak) (\"Floor\" concrete)) {options})"
        );
        let program = compile_shot(&text).unwrap_or_else(|e| panic!("{e:?}"));
        let tsv = timbre_lang::contact_score(&program.contacts);
        let rows: Vec<(f64, f64)> = tsv
            .lines()
            .skip(1)
            .map(|line| {
                let cells: Vec<&str> = line.split('\t').collect();
                (cells[1].parse().unwrap(), cells[2].parse().unwrap())
            })
            .collect();
        rows
    };
    let from_zero = score(":frame-rate 24");
    let from_one = score(":frame-rate 24 :first-frame 1");
    assert!(!from_zero.is_empty());
    for ((t0, f0), (t1, f1)) in from_zero.iter().zip(&from_one) {
        assert_eq!(t0, t1);
        assert!((f0 - t0 * 24.0).abs() < 1e-3, "{t0} s is frame {f0}");
        assert!(
            (f1 - (1.0 + t1 * 24.0)).abs() < 1e-3,
            "{t1} s is frame {f1}"
        );
    }
}

#[test]
fn a_mode_at_the_preset_s_bandwidth_decays_60_db_in_the_material_s_t60() {
    // The presets give a mode of f Hz the bandwidth η·f: a resonator of bandwidth B
    // falls by e^(−π·B·t), so by 60 dB in 3·ln 10/(π·η·f), which `Material::t60`
    // states. Struck once, measured from the envelope.
    let f = 700.0;
    let text = format!(
        "(resonz (impact :a steel :b oak :radius 0.01 :mass 0.05 :speed 1) {f} {})",
        OAK.loss * f
    );
    let stated = OAK.t60(f);
    let y = common::render(&text, &[], stated * 1.5);
    let sr = common::SR;
    // Peak amplitude in each period, after the strike.
    let period = (sr / f).ceil() as usize;
    let envelope: Vec<f64> = y
        .chunks(period)
        .map(|c| c.iter().fold(0.0f64, |m, x| m.max(x.abs())))
        .collect();
    let peak = envelope.iter().copied().fold(0.0, f64::max);
    let start = envelope.iter().position(|&e| e == peak).unwrap();
    let below = envelope[start..]
        .iter()
        .position(|&e| e < peak * 1e-3)
        .unwrap();
    let measured = below as f64 * period as f64 / sr;
    assert!(
        (measured / stated - 1.0).abs() < 0.05,
        "60 dB in {measured} s, stated {stated} s"
    );
}

#[test]
fn an_unknown_material_gets_the_closest_name() {
    let text = format!("{HEAD}(contacts shot :materials ((\"Cube\" oak) (\"Floor\" concret)))");
    let (code, message, underlined, help) = error(&text);
    assert_eq!(code, "timbre::unknown-material");
    assert_eq!(message, "unknown material `concret`");
    assert_eq!(underlined, "concret");
    assert!(help.starts_with("did you mean `concrete`?"), "{help}");
}

#[test]
fn an_object_the_shot_does_not_have_gets_the_closest_name() {
    let text = format!("{HEAD}(contacts shot :materials ((\"Cub\" oak) (\"Floor\" concrete)))");
    let (code, message, underlined, help) = error(&text);
    assert_eq!(code, "timbre::unknown-node");
    assert_eq!(message, "the shot has no node or material \"Cub\"");
    assert_eq!(underlined, "\"Cub\"");
    assert_eq!(help, "did you mean \"Cube\"?");
}

#[test]
fn a_camera_cannot_touch() {
    let text = format!("{HEAD}(contacts shot :materials ((\"Camera\" oak) (\"Floor\" concrete)))");
    let (code, message, underlined, _) = error(&text);
    assert_eq!(code, "timbre::bad-contacts");
    assert_eq!(message, "node \"Camera\" has no mesh");
    assert_eq!(underlined, "\"Camera\"");
}

#[test]
fn a_mass_that_is_not_positive_is_refused() {
    let text = format!(
        "{HEAD}(contacts shot :materials ((\"Cube\" oak) (\"Floor\" concrete)) :masses ((\"Cube\" -2)))"
    );
    let (code, message, _, _) = error(&text);
    assert_eq!(code, "timbre::bad-contacts");
    assert_eq!(
        message,
        "\"Cube\" has a mass of -2 kg; a mass must be above 0 and finite"
    );
}

#[test]
fn a_suppressed_pair_makes_no_sound_and_an_unknown_shot_is_named() {
    let text = format!(
        "{HEAD}(contacts shot :materials ((\"Cube\" oak) (\"Floor\" concrete)) :suppress ((\"Floor\" \"Cube\")))"
    );
    let program = compile_shot(&text).unwrap();
    assert!(program.instances.is_empty());
    let (code, message, underlined, _) = error(&format!(
        "{HEAD}(contacts drop :materials ((\"Cube\" oak) (\"Floor\" concrete)))"
    ));
    assert_eq!(code, "timbre::bad-contacts");
    assert_eq!(message, "no motion file is named `drop`");
    assert_eq!(underlined, "drop");
}

/// The shot with the glTF material "Wood" on the cube's mesh: a GLB's JSON chunk
/// rewritten, its binary chunk kept.
fn with_wood(glb: &[u8]) -> Vec<u8> {
    let length = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + length]).unwrap();
    let cube = json["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["name"] == "Cube")
        .unwrap()["mesh"]
        .as_u64()
        .unwrap() as usize;
    json["materials"] = serde_json::json!([{"name": "Wood"}]);
    for primitive in json["meshes"][cube]["primitives"].as_array_mut().unwrap() {
        primitive["material"] = serde_json::json!(0);
    }
    glb_with(&json, &glb[20 + length..])
}

/// A GLB of the JSON `json` and the binary chunk `bin` (its 8-byte header included).
fn glb_with(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut text = json.to_string().into_bytes();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + text.len() + bin.len()) as u32).to_le_bytes());
    out.extend((text.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(text);
    out.extend(bin);
    out
}

#[test]
fn an_object_is_bound_by_its_gltf_material() {
    let text = format!("{HEAD}(contacts shot :materials ((\"Wood\" oak) (\"Floor\" concrete)))");
    let program =
        compile_with_shot(&text, &with_wood(&cube_drop())).unwrap_or_else(|e| panic!("{e:?}"));
    let rows = &program.contacts[0].rows;
    assert!(!rows.is_empty());
    assert!(
        rows.iter().all(|r| r.a == "Cube" && r.b == "Floor"),
        "{rows:?}"
    );
}

/// The scene of `:modal` tests: the cube rings with the modes of its own mesh.
fn modal_scene(extra: &str) -> String {
    format!(
        "(scene :sample-rate 48000)\n(motion shot \"drop.glb\")\n\
         (contacts shot :materials ((\"Cube\" oak) (\"Floor\" concrete)) {extra})"
    )
}

/// Each impact strikes the cube's model where the contact is: the point and normal
/// that `timbre_motion` finds, put into the cube's own frame here from the shot's
/// poses, give (through `Model::gains`) the gains the lowering wrote, mode for mode.
/// A point left unscaled, or a normal left in the world's frame, gives others.
#[test]
fn an_object_of_modal_is_struck_by_each_impact_where_and_along_what_it_is_hit() {
    struck_where_hit(&cube_drop());
    // The same cube as a mesh half the size in a node scaled by 2: the same world,
    // the same model, and each strike's point scaled back into it.
    struck_where_hit(&with_scaled_cube(&cube_drop(), 2.0));
}

/// The shot with the cube's mesh divided by `k` and its node scaled by `k`: the same
/// solid in the world.
fn with_scaled_cube(glb: &[u8], k: f32) -> Vec<u8> {
    let length = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + length]).unwrap();
    let node = json["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .position(|n| n["name"] == "Cube")
        .unwrap();
    json["nodes"][node]["scale"] = serde_json::json!([k, k, k]);
    let mesh = json["nodes"][node]["mesh"].as_u64().unwrap() as usize;
    let accessor = json["meshes"][mesh]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    let view = json["accessors"][accessor]["bufferView"].as_u64().unwrap() as usize;
    let count = json["accessors"][accessor]["count"].as_u64().unwrap() as usize;
    let start = json["bufferViews"][view]["byteOffset"]
        .as_u64()
        .unwrap_or(0) as usize;
    for bound in ["min", "max"] {
        let values: Vec<f64> = json["accessors"][accessor][bound]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| (v.as_f64().unwrap() as f32 / k) as f64)
            .collect();
        json["accessors"][accessor][bound] = serde_json::json!(values);
    }
    // The binary chunk: 8 bytes of header, then the buffer.
    let mut bin = glb[20 + length..].to_vec();
    for i in 0..3 * count {
        let at = 8 + start + 4 * i;
        let v = f32::from_le_bytes(bin[at..at + 4].try_into().unwrap()) / k;
        bin[at..at + 4].copy_from_slice(&v.to_le_bytes());
    }
    glb_with(&json, &bin)
}

fn struck_where_hit(glb: &[u8]) {
    use glam::DVec3;
    use timbre_motion::contacts::{find_contacts, Body, ContactOptions};
    use timbre_motion::{Shot, ShotOptions};

    let program = compile_with_shot(&modal_scene(":modal (\"Cube\") :modes 12"), glb)
        .unwrap_or_else(|e| panic!("{e:?}"));
    let found = &program.contacts[0];
    assert_eq!(found.shapes.len(), 1);
    let (name, model) = &found.shapes[0];
    assert_eq!(name, "Cube");
    assert_eq!(model.modes.len(), 12);
    // Blender's cube of 0.2 m (its mesh scaled by its node), of oak: 5.6 kg, its
    // voxels a little more.
    assert!((model.mass / 5.6 - 1.0).abs() < 0.06, "{} kg", model.mass);

    let shot = Shot::read(
        glb,
        &mut |_| Err("no resources".into()),
        &ShotOptions::default(),
    )
    .unwrap();
    let cube = shot.node("Cube").unwrap();
    let bodies = [("Cube", OAK.density), ("Floor", 2300.0)].map(|(name, density)| Body {
        name: name.into(),
        node: shot.node(name).unwrap(),
        density,
        mass: None,
    });
    let contacts = find_contacts(&shot, &bodies, &ContactOptions::default()).unwrap();
    assert!(contacts.impacts.len() >= 3);
    // The lowering's gains G = A/(2π·B) of each impact instance of the cube: the
    // constant vectors beside its bank's frequencies.
    let decays: Vec<f64> = model.modes.iter().map(|m| m.decay()).collect();
    let written: Vec<Vec<f64>> = program
        .instances
        .iter()
        .filter(|i| i.stem.object.as_deref() == Some("Cube") && i.name.contains("impact"))
        .map(|i| {
            let consts: Vec<&[f64]> = program
                .graph
                .schedule(i.root)
                .into_iter()
                .filter_map(|n| program.graph.const_value(n))
                .filter(|v| v.len() == decays.len())
                .collect();
            // Not the frequencies or the bandwidths: the gains.
            let frequencies: Vec<f64> = model.modes.iter().map(|m| m.damped_frequency()).collect();
            let bandwidths: Vec<f64> = decays.iter().map(|d| d / std::f64::consts::PI).collect();
            consts
                .into_iter()
                .find(|v| *v != frequencies.as_slice() && *v != bandwidths.as_slice())
                .unwrap_or_else(|| panic!("no gains in {}", i.name))
                .to_vec()
        })
        .collect();
    assert_eq!(written.len(), contacts.impacts.len());
    let scale = shot.pose(cube, 0.0).scale;
    for (impact, gains) in contacts.impacts.iter().zip(&written) {
        // The normal points from a toward b: the force on a is along −n.
        let (local, push) = if impact.a == 0 {
            (impact.point_a, -impact.normal)
        } else {
            (impact.point_b, impact.normal)
        };
        let rotation = shot.pose(cube, impact.time).rotation;
        let strike = timbre_modal::model::Strike {
            point: (local * scale).to_array(),
            direction: (rotation.inverse() * push).to_array(),
        };
        let (pressures, point) = model.gains(&strike, 1.0);
        // The point struck is on the cube's surface, near where the contact is.
        let distance = (DVec3::from(point) - local * scale).length();
        assert!(
            distance < 2.0 * model.surface.sides.iter().cloned().fold(0.0, f64::max),
            "{distance} m off the surface"
        );
        // G·B/P is one number for every mode: the impulse's and full scale's.
        let ratios: Vec<f64> = (0..decays.len())
            .filter(|&m| {
                pressures[m].abs() > 1e-6 * pressures.iter().fold(0.0f64, |a, p| a.max(p.abs()))
            })
            .map(|m| gains[m] * decays[m] / pressures[m])
            .collect();
        assert!(ratios.len() >= 4, "{ratios:?}");
        for r in &ratios {
            assert!(
                (r / ratios[0] - 1.0).abs() < 1e-9,
                "impact at {} s: {ratios:?}",
                impact.time
            );
        }
    }
}

/// A glTF node's mesh is a `modal` shape too (`:mesh "drop.glb" :node "Cube"`), the
/// same as `contacts` makes of it; an impact rings the cube at its modes' frequencies,
/// and a file of several meshes needs `:node`.
#[test]
fn a_gltf_node_is_a_modal_shape_and_the_cube_rings_at_its_modes() {
    let program = compile_shot(&modal_scene(":modal (\"Cube\") :modes 6"))
        .unwrap_or_else(|e| panic!("{e:?}"));
    let contacts_model = program.contacts[0].shapes[0].1.clone();
    // The cube's bricks are cubes: their side, asked for, gives the same grid.
    let text = format!(
        "(modal :mesh \"drop.glb\" :node \"Cube\" :material oak :modes 6 :voxel {})",
        contacts_model.surface.sides[0]
    );
    let node = compile_shot(&text).unwrap_or_else(|e| panic!("{e:?}"));
    let model = &node.modal[0].model;
    let frequencies = |m: &timbre_modal::model::Model| -> Vec<f64> {
        m.modes.iter().map(|m| m.frequency).collect()
    };
    assert_eq!(frequencies(model), frequencies(&contacts_model));
    // The first impact of the cube alone (no listener: the instance as written),
    // rendered: its loudest partial above 3 kHz is one of its modes, within 0.5 %.
    let first = program
        .instances
        .iter()
        .find(|i| i.stem.object.as_deref() == Some("Cube") && i.name.contains("impact"))
        .unwrap();
    let config = timbre_ir::RenderConfig {
        sample_rate: common::SR,
        block_size: 256,
    };
    let mut out = vec![0.0; ((first.start + 0.2) * common::SR) as usize];
    timbre_ir::Interpreter::new(&program.graph, first.root, config).render(&mut out);
    let onset = out.iter().position(|y| y.abs() > 1e-9).expect("it sounds");
    let ring = &out[onset..];
    let peak = timbre_testkit::strongest_peak_in(ring, common::SR, 3000.0, 20_000.0);
    let closest = frequencies(model)
        .iter()
        .map(|f| (peak / f - 1.0).abs())
        .fold(f64::INFINITY, f64::min);
    assert!(
        closest < 0.005,
        "peak {peak} Hz, modes {:?}",
        frequencies(model)
    );
    let (code, message, underlined, help) =
        error("(modal :mesh \"drop.glb\" :material oak :modes 6)");
    assert_eq!(code, "timbre::bad-modal");
    assert_eq!(
        message,
        "the file has 2 nodes with meshes: name one with :node"
    );
    assert_eq!(underlined, "\"drop.glb\"");
    assert!(help.contains("Cube") && help.contains("Floor"), "{help}");
    let (code, message, underlined, help) =
        error("(modal :mesh \"drop.glb\" :node \"Cub\" :material oak :modes 6)");
    assert_eq!(code, "timbre::unknown-node");
    assert_eq!(message, "the file has no node \"Cub\" with a mesh");
    assert_eq!(
        (underlined.as_str(), help.as_str()),
        ("\"Cub\"", "did you mean \"Cube\"?")
    );
}

#[test]
fn modal_objects_are_named_in_materials_and_not_in_sounds() {
    let (code, message, underlined, help) = error(&modal_scene(":modal (\"Cub\")"));
    assert_eq!(code, "timbre::bad-contacts");
    assert_eq!(message, "\"Cub\" is not an object of :materials");
    assert_eq!(
        (underlined.as_str(), help.as_str()),
        ("\"Cub\"", "did you mean \"Cube\"?")
    );
    let (code, message, underlined, _) = error(&modal_scene(":modal (\"Cube\") :modes 0"));
    assert_eq!(code, "timbre::bad-contacts");
    assert_eq!(
        message,
        "`:modes` is 0; it counts modes: a whole number from 1"
    );
    assert_eq!(underlined, "0");
    let (code, _, underlined, _) = error(&modal_scene(":modes 12"));
    assert_eq!(
        (code.as_str(), underlined.as_str()),
        ("timbre::bad-contacts", "12")
    );
    let text = format!(
        "(define-sound knock (force) (resonz force 900 40))\n{}",
        modal_scene(":modal (\"Cube\") :sounds ((\"Cube\" knock))")
    );
    let (code, message, underlined, _) = error(&text);
    assert_eq!(code, "timbre::bad-contacts");
    assert_eq!(
        message,
        "\"Cube\" has a class of :sounds and the modes of its shape"
    );
    assert_eq!(underlined, "\"Cube\"");
}
