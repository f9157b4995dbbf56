//! The ways' filters a way to a lane: the air's two poles and the walls' pole of up
//! to [`LANES`] ways in one loop over the samples.
//!
//! One way's poles are a chain of dependent multiply-adds, sample after sample: run
//! way by way, the processor waits on that chain. Side by side, the ways' chains are
//! independent and fill a vector. Each lane's arithmetic is exactly
//! [`AirFilter::process_run`](crate::dsp::air::AirFilter::process_run)'s and then
//! [`OnePole::process_run`](crate::dsp::filter::OnePole::process_run)'s, so the bits
//! are those of filtering each way alone; a lane with a coefficient of 1 passes its
//! sound unchanged (a way without walls, a medium without air, an empty lane).

/// Ways filtered in one loop.
pub const LANES: usize = 8;

/// One sample of each lane's way.
pub type Lanes = [f64; LANES];

/// The filters' coefficients and states, a lane per way.
#[derive(Clone, Copy, Debug)]
pub struct LaneFilters {
    /// The air's coefficient `a` (both poles) and its poles' states.
    pub air: Lanes,
    pub first: Lanes,
    pub second: Lanes,
    /// The walls' coefficient and its pole's state.
    pub wall: Lanes,
    pub walls: Lanes,
}

impl Default for LaneFilters {
    /// Every lane passes its sound unchanged.
    fn default() -> Self {
        LaneFilters {
            air: [1.0; LANES],
            first: [0.0; LANES],
            second: [0.0; LANES],
            wall: [1.0; LANES],
            walls: [0.0; LANES],
        }
    }
}

impl LaneFilters {
    /// Filters the first `lanes` lanes of `block` in place (at most [`LANES`]), one
    /// sample of each at a time (on AVX2 when `wide`: the same operations, so the same
    /// bits). The other lanes are left as they are.
    pub fn run(&mut self, block: &mut [Lanes], lanes: usize, wide: bool) {
        // As many lanes as the ways need, rounded up to a vector's worth.
        match lanes {
            0..=2 => self.run_wide::<2>(block, wide),
            3..=4 => self.run_wide::<4>(block, wide),
            _ => self.run_wide::<LANES>(block, wide),
        }
    }

    fn run_wide<const N: usize>(&mut self, block: &mut [Lanes], wide: bool) {
        #[cfg(target_arch = "x86_64")]
        if wide {
            // SAFETY: `wide` is set only where the processor has AVX2.
            unsafe { self.run_avx2::<N>(block) };
            return;
        }
        let _ = wide;
        self.run_portable::<N>(block);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2<const N: usize>(&mut self, block: &mut [Lanes]) {
        self.run_portable::<N>(block);
    }

    #[inline(always)]
    fn run_portable<const N: usize>(&mut self, block: &mut [Lanes]) {
        let lanes = |x: &Lanes| -> [f64; N] { std::array::from_fn(|l| x[l]) };
        let (air, wall) = (lanes(&self.air), lanes(&self.wall));
        let (air_p, wall_p) = (air.map(|a| 1.0 - a), wall.map(|a| 1.0 - a));
        let (mut first, mut second) = (lanes(&self.first), lanes(&self.second));
        let mut walls = lanes(&self.walls);
        for v in block.iter_mut() {
            for l in 0..N {
                first[l] = air_p[l] * first[l] + air[l] * v[l];
                second[l] = air_p[l] * second[l] + air[l] * first[l];
                walls[l] = wall_p[l] * walls[l] + wall[l] * second[l];
                v[l] = walls[l];
            }
        }
        self.first[..N].copy_from_slice(&first);
        self.second[..N].copy_from_slice(&second);
        self.walls[..N].copy_from_slice(&walls);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::air::AirFilter;
    use crate::dsp::filter::OnePole;

    /// Each lane's output, over runs of several lengths, has the bits of its way
    /// filtered alone by the air's filter and then the walls' pole (or none), on
    /// every path the machine can take; so have the states after the runs.
    #[test]
    fn a_lane_has_the_bits_of_its_way_filtered_alone() {
        let n = 200;
        let runs = [(0, 64), (64, 130), (130, n)];
        let signal = |l: usize, j: usize| ((j * (l + 3)) as f64 * 0.37).sin() * (1.0 + l as f64);
        let mut lanes = LaneFilters::default();
        let mut alone = vec![];
        for l in 0..LANES {
            let mut air = AirFilter::default();
            air.set_coefficient(0.3 + 0.08 * l as f64);
            let wall = (l % 3 != 0).then_some(0.2 + 0.1 * l as f64);
            lanes.air[l] = air.parts().0;
            lanes.wall[l] = wall.unwrap_or(1.0);
            alone.push((air, OnePole::default(), wall));
        }
        let input: Vec<Lanes> = (0..n)
            .map(|j| std::array::from_fn(|l| signal(l, j)))
            .collect();
        let paths = [false, true].into_iter().filter(|&wide| !wide || avx2());
        let outputs: Vec<(Vec<Lanes>, LaneFilters)> = paths
            .map(|wide| {
                let (mut lanes, mut block) = (lanes, input.clone());
                for (start, end) in runs {
                    lanes.run(&mut block[start..end], LANES, wide);
                }
                (block, lanes)
            })
            .collect();
        for (l, (air, wall, coefficient)) in alone.iter_mut().enumerate() {
            let mut x: Vec<f64> = (0..n).map(|j| signal(l, j)).collect();
            for (start, end) in runs {
                air.process_run(&mut x[start..end], false);
                if let Some(a) = coefficient {
                    wall.process_run(*a, &mut x[start..end], false);
                }
            }
            let (_, first, second) = air.parts();
            for (block, lanes) in &outputs {
                for j in 0..n {
                    assert_eq!(block[j][l].to_bits(), x[j].to_bits(), "lane {l} sample {j}");
                }
                assert_eq!((lanes.first[l], lanes.second[l]), (first, second));
                if coefficient.is_some() {
                    assert_eq!(lanes.walls[l], wall.state());
                }
            }
        }
    }

    fn avx2() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            std::is_x86_feature_detected!("avx2")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }
}
