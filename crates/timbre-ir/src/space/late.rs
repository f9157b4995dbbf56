//! A room's late reverberation, shared by every sound in it: a send bus.
//!
//! Each placed instance's propagation writes, beside its receivers' lanes, one send
//! lane per receiver: the sound its first receiver hears directly, the late part's
//! onset later, times the late part's gain (muffled where the room's reflections are
//! blocked from that receiver). The renderer sums every instance's sends into the
//! room's bus and runs one reverberator per receiver over the sum, so a room with
//! hundreds of sources costs one network per receiver, not one per source. The
//! reverberator is linear and time-invariant, so this is the sum of one network per
//! instance (to rounding) when nothing is muffled; a muffle now acts on what enters
//! the network rather than on what leaves it.

use crate::dsp::conv::Convolver;
use crate::dsp::fdn::Fdn;
use crate::dsp::wav::resample;

use super::environment::{Acoustics, Late};

/// Partition of the late part's convolution, samples.
const LATE_PARTITION: usize = 256;

/// A room's late part heard by its receivers: what a scene's instances send to.
#[derive(Clone, Debug)]
pub struct LateBus {
    pub acoustics: Acoustics,
    /// Each receiver's share of the diffuse field ([`Pickup::diffuse`]), a lane in and
    /// out each: its output's gain, and 0 for a lane that hears none (whose
    /// reverberator is not run).
    ///
    /// [`Pickup::diffuse`]: super::Pickup::diffuse
    pub shares: Vec<f64>,
}

impl LateBus {
    /// The bus of `acoustics` for receivers of diffuse-field `shares`, if the room
    /// has a late part.
    pub fn of(acoustics: &Acoustics, shares: Vec<f64>) -> Option<LateBus> {
        (!matches!(acoustics.late, Late::None)).then(|| LateBus {
            acoustics: acoustics.clone(),
            shares,
        })
    }

    /// Whether `other` is the same room heard by as many receivers (its instances
    /// may share it).
    pub fn same(&self, other: &LateBus) -> bool {
        let describe = |bus: &LateBus| {
            let mut d = crate::op::Description::new();
            bus.acoustics.describe(&mut d);
            d.f64s(&bus.shares);
            d
        };
        describe(self) == describe(other)
    }

    /// Receivers (lanes in and out).
    pub fn lanes(&self) -> usize {
        self.shares.len()
    }

    /// How long it rings after its last input, seconds.
    pub fn tail(&self) -> f64 {
        match &self.acoustics.late {
            Late::None => 0.0,
            Late::Fdn { rt60, .. } => rt60.iter().fold(0.0, |m: f64, t| m.max(*t)),
            Late::Convolution { response, .. } => {
                response.frames.len() as f64 / response.sample_rate
            }
        }
    }

    /// Its reverberators at `sample_rate`, silent.
    pub fn new_state(&self, sample_rate: f64) -> LateBusState {
        let reverb = |share: f64| match &self.acoustics.late {
            _ if share == 0.0 => Reverb::Silent,
            Late::Fdn { rt60, .. } => {
                Reverb::Network(Box::new(self.acoustics.network(rt60, sample_rate)))
            }
            Late::Convolution { response, .. } => Reverb::Convolution(Box::new(Convolver::new(
                &resample(response, sample_rate),
                LATE_PARTITION,
            ))),
            Late::None => Reverb::Silent,
        };
        LateBusState {
            reverbs: self.shares.iter().map(|s| reverb(*s)).collect(),
            shares: self.shares.clone(),
            run: vec![0.0; LATE_PARTITION],
        }
    }
}

/// What makes the late part.
#[derive(Debug)]
enum Reverb {
    Network(Box<Fdn>),
    Convolution(Box<Convolver>),
    Silent,
}

/// A bus's reverberators, one per receiver.
#[derive(Debug)]
pub struct LateBusState {
    reverbs: Vec<Reverb>,
    shares: Vec<f64>,
    /// One lane's input, gathered from the interleaved frames.
    run: Vec<f64>,
}

impl LateBusState {
    /// Receivers (lanes in and out).
    pub fn lanes(&self) -> usize {
        self.reverbs.len()
    }

    /// Silences every reverberator, as when new (allocates nothing).
    pub fn reset(&mut self) {
        for reverb in &mut self.reverbs {
            match reverb {
                Reverb::Network(fdn) => fdn.reset(),
                Reverb::Convolution(convolver) => convolver.reset(),
                Reverb::Silent => {}
            }
        }
    }

    /// Adds the late part of `input` (frames of one sample per receiver,
    /// interleaved) into `out` (frames of as many lanes). Receiver k hears output
    /// k mod 2 of its network (so a pair of receivers hears two uncorrelated
    /// outputs), or its convolution with the room's recorded response, fed its
    /// share of the input.
    pub fn process(&mut self, input: &[f64], out: &mut [f64]) {
        let lanes = self.reverbs.len();
        if lanes == 0 {
            return;
        }
        let frames = input.len() / lanes;
        for (k, (reverb, share)) in self.reverbs.iter_mut().zip(&self.shares).enumerate() {
            if matches!(reverb, Reverb::Silent) {
                continue;
            }
            let mut from = 0;
            while from < frames {
                let n = (frames - from).min(self.run.len());
                let run = &mut self.run[..n];
                for (j, x) in run.iter_mut().enumerate() {
                    *x = input[(from + j) * lanes + k] * share;
                }
                match reverb {
                    Reverb::Network(fdn) => {
                        for (j, x) in run.iter().enumerate() {
                            out[(from + j) * lanes + k] += fdn.process(*x)[k % 2];
                        }
                    }
                    Reverb::Convolution(convolver) => {
                        let mut y = [0.0; LATE_PARTITION];
                        convolver.process(run, &mut y[..n]);
                        for (j, y) in y[..n].iter().enumerate() {
                            out[(from + j) * lanes + k] += y;
                        }
                    }
                    Reverb::Silent => {}
                }
                from += n;
            }
        }
    }
}
