//! A node's motion as a `timbre_ir::motion::Trajectory`.

use std::sync::Arc;

use glam::{DVec3, DVec4};
use timbre_ir::motion::{Kinematics, Trajectory};
use timbre_ir::op::Description;

use crate::jet::{cross, dot, length, normalize, transform, Jet};
use crate::{to_timbre, ShotData};

/// What a [`NodeTrajectory`] follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeQuantity {
    Position,
    Forward,
    Up,
    AngularVelocity,
    /// The world scale along the node's own axes, in timbre's order (Blender's
    /// x, y, z scale): the lengths of its world x, −z and y axes.
    Scale,
}

impl NodeQuantity {
    pub fn name(self) -> &'static str {
        match self {
            NodeQuantity::Position => "position",
            NodeQuantity::Forward => "forward",
            NodeQuantity::Up => "up",
            NodeQuantity::AngularVelocity => "angular-velocity",
            NodeQuantity::Scale => "scale",
        }
    }
}

/// One quantity of one node of a shot.
#[derive(Clone, Debug)]
pub struct NodeTrajectory {
    shot: Arc<ShotData>,
    node: usize,
    quantity: NodeQuantity,
}

impl NodeTrajectory {
    pub(crate) fn new(shot: Arc<ShotData>, node: usize, quantity: NodeQuantity) -> Self {
        NodeTrajectory {
            shot,
            node,
            quantity,
        }
    }
}

fn kinematics(jet: Jet<DVec3>) -> Kinematics {
    Kinematics {
        position: to_timbre(jet.value),
        velocity: to_timbre(jet.d1),
        acceleration: to_timbre(jet.d2),
    }
}

impl Trajectory for NodeTrajectory {
    fn key_times(&self) -> Vec<f64> {
        self.shot.key_times(self.node)
    }

    fn kinematics(&self, t: f64) -> Kinematics {
        if self.node >= self.shot.nodes.len() {
            return Kinematics::default();
        }
        let world = self.shot.world(self.node, t);
        let axis = |v: DVec4| transform(&world, v);
        match self.quantity {
            NodeQuantity::Position => kinematics(axis(DVec4::W)),
            NodeQuantity::Forward => kinematics(normalize(axis(DVec4::NEG_Z))),
            NodeQuantity::Up => kinematics(normalize(axis(DVec4::Y))),
            NodeQuantity::Scale => {
                let [x, y, z] = [DVec4::X, DVec4::NEG_Z, DVec4::Y].map(|a| length(axis(a)));
                Kinematics {
                    position: DVec3::new(x.value, y.value, z.value),
                    velocity: DVec3::new(x.d1, y.d1, z.d1),
                    acceleration: DVec3::new(x.d2, y.d2, z.d2),
                }
            }
            NodeQuantity::AngularVelocity => {
                // The orthonormal frame of the world x and y axes (Gram–Schmidt);
                // ω = ½ Σ eᵢ × eᵢ' and ω' = ½ Σ eᵢ × eᵢ'' (as eᵢ' × eᵢ' = 0).
                let e0 = normalize(axis(DVec4::X));
                let y = axis(DVec4::Y);
                let e1 = normalize(y - e0.scaled(dot(y, e0)));
                let e2 = cross(e0, e1);
                let half = |f: fn(&Jet<DVec3>) -> DVec3| {
                    [e0, e1, e2]
                        .iter()
                        .map(|e| e.value.cross(f(e)))
                        .sum::<DVec3>()
                        * 0.5
                };
                Kinematics {
                    position: to_timbre(half(|e| e.d1)),
                    velocity: to_timbre(half(|e| e.d2)),
                    acceleration: DVec3::ZERO,
                }
            }
        }
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        let Some(node) = self.shot.nodes.get(self.node) else {
            return (DVec3::ZERO, DVec3::ZERO);
        };
        let b = &node.bounds;
        match self.quantity {
            NodeQuantity::Position => {
                let (lo, hi) = (to_timbre(b.box_lo), to_timbre(b.box_hi));
                (lo.min(hi), lo.max(hi))
            }
            NodeQuantity::Forward | NodeQuantity::Up => (-DVec3::ONE, DVec3::ONE),
            // Not a place: no bound is computed.
            NodeQuantity::Scale => (DVec3::ZERO, DVec3::INFINITY),
            NodeQuantity::AngularVelocity => {
                let w = b.angular_speed();
                (-DVec3::splat(w), DVec3::splat(w))
            }
        }
    }

    fn max_speed(&self) -> f64 {
        let Some(node) = self.shot.nodes.get(self.node) else {
            return 0.0;
        };
        let b = &node.bounds;
        match self.quantity {
            NodeQuantity::Position => b.speed,
            NodeQuantity::Forward | NodeQuantity::Up => b.turn_rate(),
            // No bound of the angular acceleration, or of how fast a scale changes, is
            // computed.
            NodeQuantity::AngularVelocity | NodeQuantity::Scale => f64::INFINITY,
        }
    }

    fn describe(&self, d: &mut Description) {
        d.str("gltf-node")
            .u64(self.shot.hash)
            .u64(self.node as u64)
            .str(self.quantity.name());
    }

    fn detail(&self) -> String {
        let name = self
            .shot
            .nodes
            .get(self.node)
            .and_then(|n| n.name.clone())
            .unwrap_or_else(|| format!("#{}", self.node));
        format!(
            "{} of glTF node \"{name}\" (shot {:016x})",
            self.quantity.name(),
            self.shot.hash
        )
    }
}
