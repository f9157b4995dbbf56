//! A small wind-driven simulation of five wind chimes and their striker (after Hahn
//! et al. 1995, Figures 7–8), for `examples/wind-chimes.tt`: its collisions and its
//! motion are the example's data (`examples/data/chime-hits.csv`,
//! `examples/data/chime-motion.csv`), and a test holds the files to this code.
//!
//! Five tubes hang on a ring around a striker. Each hangs from its top and swings
//! as a physical pendulum (its bottom displaced in the horizontal plane); the
//! striker is a simple pendulum. A gusty wind of turning direction pushes each body
//! with quadratic drag, plus a turbulent part; the striker hits a tube when they
//! touch while approaching, with restitution. Everything is deterministic: the same
//! code gives the same files, to the digit.

/// Tube lengths, metres, longest first (aluminium, 25 mm outer, 22 mm inner).
pub const LENGTHS: [f64; 5] = [0.46, 0.41, 0.37, 0.33, 0.30];
/// Seconds simulated.
pub const SECONDS: f64 = 20.0;
/// Frames per second of the motion file.
pub const FRAME_RATE: f64 = 30.0;

const G: f64 = 9.81;
const AIR: f64 = 1.2;
const RING: f64 = 0.055;
const STRIKER_RADIUS: f64 = 0.022;
const TUBE_RADIUS: f64 = 0.0125;
const STRIKER_MASS: f64 = 0.05;
const STRIKER_LENGTH: f64 = 0.25;
const STRIKER_AREA: f64 = 0.006;
const TUBE_MASS_PER_METRE: f64 = 0.45;
const RESTITUTION: f64 = 0.5;
const DAMPING: f64 = 0.4;
/// The integration step: 160 steps to a frame.
const STEP: f64 = 1.0 / 4800.0;

/// One collision of the striker with a tube.
#[derive(Clone, Debug, PartialEq)]
pub struct Hit {
    pub time: f64,
    /// 1 to 5.
    pub chime: usize,
    /// Closing speed along the contact normal, m/s.
    pub speed: f64,
}

/// The state at one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub time: f64,
    /// The wind's total force on the six bodies, N.
    pub wind: f64,
    /// Each tube's bottom displaced outward from the ring's centre, cm.
    pub displacement: [f64; 5],
}

/// The wind speed (m/s) and direction (radians) at `t`: slow gusts, a turning
/// direction.
fn wind(t: f64) -> (f64, f64) {
    let tau = std::f64::consts::TAU;
    let gusts = 0.55 * (tau * 0.061 * t).sin()
        + 0.3 * (tau * 0.173 * t + 1.3).sin()
        + 0.15 * (tau * 0.41 * t + 0.4).sin();
    let speed = (4.0 + 3.5 * gusts).max(0.0);
    let direction = 1.4 * (tau * 0.029 * t).sin()
        + 0.9 * (tau * 0.083 * t + 2.0).sin()
        + 0.4 * (tau * 0.21 * t).sin();
    (speed, direction)
}

/// The turbulent part of the wind on body `k`, a fraction of the mean push: a few
/// incommensurate sines per axis.
fn turbulence(t: f64, k: usize) -> [f64; 2] {
    let tau = std::f64::consts::TAU;
    let phase = k as f64 * 1.7;
    [
        0.6 * (tau * 1.31 * t + phase).sin() + 0.4 * (tau * 2.93 * t + 2.0 * phase).sin(),
        0.6 * (tau * 1.87 * t + 0.5 + phase).sin() + 0.4 * (tau * 3.71 * t + phase).sin(),
    ]
}

struct Body {
    position: [f64; 2],
    velocity: [f64; 2],
    /// Where it hangs at rest.
    rest: [f64; 2],
    mass: f64,
    /// ω², 1/s².
    stiffness: f64,
    area: f64,
}

/// Runs the simulation: every hit, and a frame every 1/FRAME_RATE s.
pub fn simulate() -> (Vec<Hit>, Vec<Frame>) {
    let mut bodies: Vec<Body> = vec![Body {
        position: [0.0, 0.0],
        velocity: [0.0, 0.0],
        rest: [0.0, 0.0],
        mass: STRIKER_MASS,
        stiffness: G / STRIKER_LENGTH,
        area: STRIKER_AREA,
    }];
    for (i, length) in LENGTHS.iter().enumerate() {
        let angle = std::f64::consts::TAU * i as f64 / 5.0;
        let rest = [RING * angle.cos(), RING * angle.sin()];
        bodies.push(Body {
            position: rest,
            velocity: [0.0, 0.0],
            rest,
            mass: TUBE_MASS_PER_METRE * length,
            // A rod hung from one end: ω² = 3g / 2L (its bottom's displacement).
            stiffness: 3.0 * G / (2.0 * length),
            area: length * 2.0 * TUBE_RADIUS,
        });
    }
    let steps = (SECONDS / STEP).round() as u64;
    let frame_every = (1.0 / (FRAME_RATE * STEP)).round() as u64;
    let (mut hits, mut frames) = (vec![], vec![]);
    for step in 0..=steps {
        let t = step as f64 * STEP;
        let (speed, direction) = wind(t);
        let push = 0.5 * AIR * 1.2 * speed * speed;
        let mut total = 0.0;
        for (k, body) in bodies.iter_mut().enumerate() {
            let gust = turbulence(t, k);
            let force = [
                push * body.area * (direction.cos() + 0.5 * gust[0]),
                push * body.area * (direction.sin() + 0.5 * gust[1]),
            ];
            total += force[0].hypot(force[1]);
            for (axis, push) in force.iter().enumerate() {
                let offset = body.position[axis] - body.rest[axis];
                let accel =
                    push / body.mass - body.stiffness * offset - DAMPING * body.velocity[axis];
                body.velocity[axis] += accel * STEP;
                body.position[axis] += body.velocity[axis] * STEP;
            }
        }
        for chime in 1..bodies.len() {
            if let Some(speed) = collide(&mut bodies, chime) {
                if speed > 0.01 {
                    hits.push(Hit {
                        time: t,
                        chime,
                        speed,
                    });
                }
            }
        }
        if step % frame_every == 0 {
            let displacement = std::array::from_fn(|i| {
                let body = &bodies[i + 1];
                let outward = [body.rest[0] / RING, body.rest[1] / RING];
                let offset = [
                    body.position[0] - body.rest[0],
                    body.position[1] - body.rest[1],
                ];
                100.0 * (offset[0] * outward[0] + offset[1] * outward[1])
            });
            frames.push(Frame {
                time: t,
                wind: total,
                displacement,
            });
        }
    }
    (hits, frames)
}

/// The striker (body 0) against tube `chime`: if they touch while closing, an
/// impulse with restitution parts them; returns the closing speed.
fn collide(bodies: &mut [Body], chime: usize) -> Option<f64> {
    let (striker, tubes) = bodies.split_at_mut(1);
    let (s, c) = (&mut striker[0], &mut tubes[chime - 1]);
    let gap = [c.position[0] - s.position[0], c.position[1] - s.position[1]];
    let distance = gap[0].hypot(gap[1]);
    let contact = STRIKER_RADIUS + TUBE_RADIUS;
    if distance >= contact || distance == 0.0 {
        return None;
    }
    let normal = [gap[0] / distance, gap[1] / distance];
    let closing =
        (s.velocity[0] - c.velocity[0]) * normal[0] + (s.velocity[1] - c.velocity[1]) * normal[1];
    if closing <= 0.0 {
        return None;
    }
    let impulse = (1.0 + RESTITUTION) * closing / (1.0 / s.mass + 1.0 / c.mass);
    for (axis, n) in normal.iter().enumerate() {
        s.velocity[axis] -= impulse / s.mass * n;
        c.velocity[axis] += impulse / c.mass * n;
    }
    Some(closing)
}

/// The hits as CSV: `time,chime,speed,length` (seconds, 1–5, m/s, metres).
pub fn hits_csv(hits: &[Hit]) -> String {
    let mut text = String::from("time,chime,speed,length\n");
    for hit in hits {
        text += &format!(
            "{:.4},{},{:.4},{}\n",
            hit.time,
            hit.chime,
            hit.speed,
            LENGTHS[hit.chime - 1]
        );
    }
    text
}

/// The frames as CSV: `time,wind,c1,…,c5` (seconds, N, cm).
pub fn motion_csv(frames: &[Frame]) -> String {
    let mut text = String::from("time,wind,c1,c2,c3,c4,c5\n");
    for frame in frames {
        text += &format!("{:.4},{:.5}", frame.time, frame.wind);
        for d in frame.displacement {
            // Rounded first, so that a tiny negative value is written 0, not −0.
            text += &format!(",{:.4}", (d * 1e4).round() / 1e4 + 0.0);
        }
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wind_strikes_every_chime_in_time_order() {
        let (hits, frames) = simulate();
        for chime in 1..=5 {
            assert!(
                hits.iter().any(|h| h.chime == chime),
                "chime {chime} is never hit"
            );
        }
        assert!(hits.windows(2).all(|w| w[0].time <= w[1].time));
        assert!(hits.iter().all(|h| h.speed > 0.01 && h.speed < 2.0));
        assert_eq!(frames.len(), (SECONDS * FRAME_RATE) as usize + 1);
        // The tubes swing (centimetres) and the wind gusts (its force varies).
        let swing = frames
            .iter()
            .flat_map(|f| f.displacement)
            .fold(0.0, |a: f64, d| a.max(d.abs()));
        assert!((1.0..20.0).contains(&swing), "{swing}");
        let (lo, hi) = frames.iter().fold((f64::MAX, 0.0f64), |(lo, hi), f| {
            (lo.min(f.wind), hi.max(f.wind))
        });
        assert!(hi > 5.0 * lo, "{lo}..{hi}");
        assert_eq!(simulate(), (hits, frames));
    }
}
