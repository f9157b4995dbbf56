//! Near-valid programs (generated trees with a few mistakes, `timbre_gen::mutate`):
//! whatever they are, lowering answers with a program or diagnostics, and a program
//! within modest limits renders in both engines, never panicking.

mod support;

use proptest::prelude::*;
use rand::SeedableRng;
use support::fuzz::try_program;
use timbre_gen::generate::{random_tree, GenConfig};
use timbre_jit::Jit;

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn near_valid_programs_get_diagnostics_or_render(tree_seed: u64, mistake_seed: u64) {
        let config = GenConfig { max_nodes: 30, ..GenConfig::default() };
        let tree = random_tree(&mut rand::rngs::StdRng::seed_from_u64(tree_seed), &config);
        let mut rng = rand::rngs::StdRng::seed_from_u64(mistake_seed);
        let text = timbre_gen::mutate::near_valid(&mut rng, &tree, 3);
        let mut jit = Jit::new().unwrap();
        try_program(&mut jit, &text);
    }
}

/// The generator is near enough to valid to reach the engines often, and far enough
/// to be refused often: both halves of the front end are exercised.
#[test]
fn near_valid_programs_reach_both_outcomes() {
    let mut jit = Jit::new().unwrap();
    let config = GenConfig {
        max_nodes: 30,
        ..GenConfig::default()
    };
    let mut rendered = 0;
    for seed in 0..200u64 {
        let tree = random_tree(&mut rand::rngs::StdRng::seed_from_u64(seed), &config);
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x5eed);
        let text = timbre_gen::mutate::near_valid(&mut rng, &tree, 2);
        rendered += usize::from(try_program(&mut jit, &text));
    }
    assert!((20..180).contains(&rendered), "{rendered} of 200 rendered");
}
