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

#[test]
fn a_mode_at_the_preset_s_bandwidth_decays_60_db_in_the_material_s_t60() {
    // The presets give a mode of f Hz the bandwidth η·f: a resonator of bandwidth B
    // falls by e^(−π·B·t), so by 60 dB in 3·ln 10/(π·η·f), which `Material::t60`
    // states. Struck once, measured from the envelope.
    let f = 700.0;
    let text = format!(
        "(resonator (impact :a steel :b oak :radius 0.01 :mass 0.05 :speed 1) {f} {})",
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
    let mut text = json.to_string().into_bytes();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let bin = &glb[20 + length..];
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
