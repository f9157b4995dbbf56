//! The bouncing-cubes example: each impact of the simulation is an onset in its
//! soundtrack, on the impact's sample.

#[path = "../examples/bouncing_cubes/sim.rs"]
mod sim;

const SR: f64 = 48_000.0;

#[test]
fn each_impact_is_an_onset_on_its_sample() {
    let impacts = sim::simulate(&sim::cubes(), 4.0);
    assert!(impacts.len() >= 8, "{} impacts", impacts.len());
    assert!(impacts.iter().any(|i| i.material == sim::Material::Wood));
    assert!(impacts.iter().any(|i| i.material == sim::Material::Metal));
    let engine = timbre::Engine::new(SR).with_seed(7);
    for k in 0..impacts.len() {
        let until = impacts[k].time + 0.01;
        // The soundtrack with and without impact k differ exactly by its sound.
        let with = sim::soundtrack(&engine, &impacts[..=k], until).unwrap();
        let without = sim::soundtrack(&engine, &impacts[..k], until).unwrap();
        let onset = with
            .iter()
            .zip(&without)
            .position(|(a, b)| a != b)
            .expect("an onset");
        let sample = (impacts[k].time * SR).round() as usize;
        // The start sample itself is the timer's 0; the sound is there from the next.
        assert!(
            onset == sample + 1,
            "impact {k} at sample {sample}, onset at {onset}"
        );
    }
}

#[test]
fn the_physics_is_exact() {
    // Dropped from 1.2 m at rest: the first impact at sqrt(2h/g), at speed sqrt(2gh).
    let impacts = sim::simulate(&sim::cubes()[..1], 4.0);
    let expected = (2.0 * 1.2 / 9.81f64).sqrt();
    assert!((impacts[0].time - expected).abs() < 1e-12);
    assert!((impacts[0].speed - (2.0 * 9.81 * 1.2f64).sqrt()).abs() < 1e-12);
    // Each flight after a bounce lasts 2·v/g with v the bounce speed.
    let flight = impacts[1].time - impacts[0].time;
    assert!((flight - 2.0 * 0.55 * impacts[0].speed / 9.81).abs() < 1e-12);
}

#[test]
fn louder_impacts_are_louder() {
    let impacts = sim::simulate(&sim::cubes()[..1], 4.0);
    let engine = timbre::Engine::new(SR).with_seed(7);
    let peak = |i: &sim::Impact| {
        let x = sim::soundtrack(&engine, std::slice::from_ref(i), i.time + 0.05).unwrap();
        x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    };
    let (first, second) = (peak(&impacts[0]), peak(&impacts[1]));
    assert!(
        (second / first - impacts[1].speed / impacts[0].speed).abs() < 0.05,
        "{first} {second}"
    );
}
