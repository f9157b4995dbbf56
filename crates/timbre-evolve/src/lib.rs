//! Genetic search over timbre trees, after the 1993 paper's section 3.3 and Sims'
//! genetic images: a sound class is a [`Genome`]; [`mutate()`] and [`crossover`] make
//! offspring with the paper's operators ([`Operator`]), and keep only those that
//! lower, render to something worth hearing and stay within the size and depth limits
//! ([`check()`]): no sample that is not finite, no silence, no constant; a sound that
//! clips is scaled back (lang-spec/evolution.md).
//!
//! ```
//! use rand::SeedableRng;
//! use timbre_evolve::{mutate, Genome, Settings};
//!
//! let seed = "(define-sound bee (f) (* 0.5 (sine (* t f))))\n(instance b (bee 220))";
//! let parent = Genome::from_source(seed, None).unwrap();
//! let mut rng = rand::rngs::StdRng::seed_from_u64(1);
//! let child = mutate(&mut rng, &parent, &Settings::default()).unwrap();
//! assert_ne!(child.genome.body, parent.body);
//! assert!(child.checked.samples.iter().all(|x| x.abs() <= 1.0));
//! ```

pub mod check;
pub mod genome;
pub mod mutate;
pub mod target;

pub use check::{check, Audition, Checked, Refusal};
pub use genome::{Genome, GenomeError};
pub use mutate::{apply, crossover, mutate, perturb, Barren, Offspring, Operator, Settings};
pub use target::{search, tune, Found, Knobs, Search, Target, Tuned};
