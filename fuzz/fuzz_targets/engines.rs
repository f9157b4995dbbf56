//! Both engines on programs of unknown quality with a sample budget: generated trees
//! with a few mistakes (when the first byte is odd: two seeds follow), or the input
//! itself as text (when it is even). Never a panic or an abort.
#![no_main]

use std::cell::RefCell;

use libfuzzer_sys::fuzz_target;
use rand::SeedableRng;
use timbre_gen::generate::{random_tree, GenConfig};
use timbre_jit::Jit;

#[path = "../../crates/timbre-jit/tests/support/fuzz.rs"]
mod support;

thread_local! {
    static JIT: RefCell<Jit> = RefCell::new(Jit::new().expect("a JIT for this machine"));
}

fuzz_target!(|data: &[u8]| {
    let text = match data.first() {
        Some(mode) if mode % 2 == 1 && data.len() >= 17 => {
            let seed = |bytes: &[u8]| u64::from_le_bytes(bytes.try_into().unwrap());
            let config = GenConfig { max_nodes: 30, ..GenConfig::default() };
            let tree = random_tree(
                &mut rand::rngs::StdRng::seed_from_u64(seed(&data[1..9])),
                &config,
            );
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed(&data[9..17]));
            timbre_gen::mutate::near_valid(&mut rng, &tree, 3)
        }
        Some(_) => match std::str::from_utf8(&data[1..]) {
            Ok(text) => text.to_owned(),
            Err(_) => return,
        },
        None => return,
    };
    JIT.with(|jit| support::try_program(&mut jit.borrow_mut(), &text));
});
