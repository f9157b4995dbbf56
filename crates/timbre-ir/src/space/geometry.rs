//! Geometry of the space: obstacles, rooms and the paths sound takes between them.
//!
//! Conventions, used throughout:
//!
//! - Units are metres; every quantity is `f64` ([`DVec3`]).
//! - Right-handed coordinates with **z up**; a listener faces +y by default.
//! - Queries never panic and never allocate: degenerate shapes (zero-size boxes,
//!   zero-area walls, flat rooms) and non-finite inputs block nothing, contain
//!   nothing and produce no paths. The `validate` methods say *why* a shape is
//!   degenerate so the caller can turn it into a diagnostic.
//! - Contacts closer than [`CONTACT_EPS`] to a segment's endpoints count as
//!   touching, not crossing: a source standing on a cabinet or against a wall is
//!   not blocked by it.
//!
//! The classification follows Table 1 of the paper (occlusion, exclusion and
//! obstruction): the direct segment from source to receiver is tested against
//! the obstacles, and so is every leg of every reflected path of a shoebox
//! [`Room`] (image-source method, Allen & Berkley).

use glam::DVec3;

/// Distance (metres) within which a contact with an obstacle counts as touching
/// a segment's endpoint rather than crossing the segment.
pub const CONTACT_EPS: f64 = 1e-9;

/// The highest reflection order an [`ImageSource`] can have; it bounds the fixed
/// arrays in [`ImageSource`] and [`ReflectionPath`] so the per-query path needs
/// no allocation. Larger requested orders are clamped to this.
pub const MAX_ORDER: usize = 6;

/// The default image-source order: first- and second-order reflections.
pub const DEFAULT_ORDER: usize = 2;

/// Smallest wall area (m²) that is not degenerate.
const MIN_AREA: f64 = 1e-12;

/// Why a shape cannot be used as given. Queries on such a shape are still safe
/// (they block nothing); these reasons exist so the caller can report them.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Degenerate {
    /// A box whose centre or half-size has a NaN or infinite component.
    #[error("box has a non-finite centre or size")]
    BoxNotFinite,
    /// A box with a zero or negative half-size along some axis.
    #[error("box has zero size along some axis (half-size {half_size}); it blocks nothing")]
    BoxZeroSize {
        /// The offending half-size, metres.
        half_size: DVec3,
    },
    /// A wall whose origin or edge vectors have a NaN or infinite component.
    #[error("wall has a non-finite corner or edge")]
    WallNotFinite,
    /// A wall whose edge vectors span (almost) no area.
    #[error("wall has zero area ({area} m²): its edges are zero or parallel; it blocks nothing")]
    WallZeroArea {
        /// |u × v|, square metres.
        area: f64,
    },
    /// An opening with non-finite bounds.
    #[error("opening {index} has non-finite bounds")]
    OpeningNotFinite {
        /// Index of the opening in [`Wall::openings`].
        index: usize,
    },
    /// An opening with `s0 >= s1` or `t0 >= t1`.
    #[error("opening {index} is empty (its start is not before its end)")]
    OpeningEmpty {
        /// Index of the opening in [`Wall::openings`].
        index: usize,
    },
    /// An opening reaching outside its wall; only the part inside matters.
    #[error(
        "opening {index} reaches outside its wall \
         (the wall is {width} m along u and {height} m along v)"
    )]
    OpeningOutside {
        /// Index of the opening in [`Wall::openings`].
        index: usize,
        /// |u|, metres.
        width: f64,
        /// |v|, metres.
        height: f64,
    },
    /// A room with a non-finite corner.
    #[error("room has a non-finite corner")]
    RoomNotFinite,
    /// A room whose `max` is not above its `min` on every axis.
    #[error("room has zero or negative size ({size} m); it has no reflections")]
    RoomZeroSize {
        /// `max - min`, metres.
        size: DVec3,
    },
}

// ---------------------------------------------------------------------------
// Obstacles
// ---------------------------------------------------------------------------

/// An axis-aligned box (a cabinet, a pillar). It is a closed solid: its surface
/// blocks too. The centre is a plain field so a moving obstacle is updated in
/// place by the caller before each query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignedBox {
    /// Centre, metres.
    pub centre: DVec3,
    /// Half the size along x, y and z, metres; all must be positive.
    pub half_size: DVec3,
}

impl AlignedBox {
    /// A box from its centre and half-size (metres).
    pub fn new(centre: DVec3, half_size: DVec3) -> Self {
        Self { centre, half_size }
    }

    /// A box from two opposite corners (any order), metres.
    pub fn from_corners(a: DVec3, b: DVec3) -> Self {
        Self {
            centre: (a + b) * 0.5,
            half_size: (b - a).abs() * 0.5,
        }
    }

    /// Why the box is degenerate, if it is.
    pub fn validate(&self) -> Result<(), Degenerate> {
        if !self.centre.is_finite() || !self.half_size.is_finite() {
            return Err(Degenerate::BoxNotFinite);
        }
        if self.half_size.min_element() <= 0.0 {
            return Err(Degenerate::BoxZeroSize {
                half_size: self.half_size,
            });
        }
        Ok(())
    }

    /// Whether `p` is strictly inside the box (not on its surface). Used to
    /// diagnose a source or receiver placed inside an obstacle, where every
    /// path out of it is blocked.
    pub fn contains(&self, p: DVec3) -> bool {
        self.validate().is_ok() && (p - self.centre).abs().cmplt(self.half_size).all()
    }

    /// Whether the open segment from `a` to `b` meets the (closed) box. Touching
    /// at an endpoint does not count; a segment starting inside the box is
    /// blocked; grazing a face or an edge between the endpoints is blocked.
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        if self.validate().is_err() || !a.is_finite() || !b.is_finite() {
            return false;
        }
        let d = b - a;
        let len = d.length();
        if len == 0.0 || !len.is_finite() {
            return false;
        }
        let lo = self.centre - self.half_size;
        let hi = self.centre + self.half_size;
        let mut t_enter = f64::NEG_INFINITY;
        let mut t_exit = f64::INFINITY;
        for axis in 0..3 {
            let (a_c, d_c, lo_c, hi_c) = (a[axis], d[axis], lo[axis], hi[axis]);
            if d_c == 0.0 {
                if a_c < lo_c || a_c > hi_c {
                    return false;
                }
            } else {
                let t1 = (lo_c - a_c) / d_c;
                let t2 = (hi_c - a_c) / d_c;
                t_enter = t_enter.max(t1.min(t2));
                t_exit = t_exit.min(t1.max(t2));
            }
        }
        // The segment meets the closed box for t in [t_enter, t_exit]; it must
        // overlap the segment away from its endpoints.
        let eps = (CONTACT_EPS / len).min(0.25);
        t_enter <= t_exit && t_exit > eps && t_enter < 1.0 - eps
    }
}

/// A rectangular hole in a [`Wall`] (a window or a door), in metres measured
/// from the wall's origin along its edges: `s` along `u`, `t` along `v`.
/// Sound passes through its open interior; its frame (the boundary) is solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Opening {
    /// Start along `u`, metres.
    pub s0: f64,
    /// Start along `v`, metres.
    pub t0: f64,
    /// End along `u`, metres.
    pub s1: f64,
    /// End along `v`, metres.
    pub t1: f64,
}

impl Opening {
    /// An opening spanning `s0..s1` along `u` and `t0..t1` along `v`, metres.
    pub fn new(s0: f64, t0: f64, s1: f64, t1: f64) -> Self {
        Self { s0, t0, s1, t1 }
    }

    fn admits(&self, s: f64, t: f64) -> bool {
        self.s0 < s && s < self.s1 && self.t0 < t && t < self.t1
    }
}

/// A thin planar wall: the parallelogram `origin + α·u + β·v` for α, β in
/// [0, 1] (a rectangle when `u ⟂ v`), with zero thickness and optional
/// [`Opening`]s. Its edges count as solid; a segment lying in its plane is not
/// blocked (a zero-thickness wall has no side to hit).
#[derive(Debug, Clone, PartialEq)]
pub struct Wall {
    /// One corner, metres.
    pub origin: DVec3,
    /// First edge from `origin`, metres.
    pub u: DVec3,
    /// Second edge from `origin`, metres.
    pub v: DVec3,
    /// Holes in the wall, metres along `u` and `v` from `origin`.
    pub openings: Vec<Opening>,
}

impl Wall {
    /// A wall without openings from a corner and two edge vectors (metres).
    pub fn new(origin: DVec3, u: DVec3, v: DVec3) -> Self {
        Self {
            origin,
            u,
            v,
            openings: Vec::new(),
        }
    }

    /// The same wall with one more opening.
    pub fn with_opening(mut self, opening: Opening) -> Self {
        self.openings.push(opening);
        self
    }

    /// The wall's normal `u × v` (not normalised; its length is the area).
    pub fn normal(&self) -> DVec3 {
        self.u.cross(self.v)
    }

    /// Why the wall or one of its openings is degenerate, if it is.
    pub fn validate(&self) -> Result<(), Degenerate> {
        if !self.origin.is_finite() || !self.u.is_finite() || !self.v.is_finite() {
            return Err(Degenerate::WallNotFinite);
        }
        let area = self.normal().length();
        if area.is_nan() || area <= MIN_AREA {
            return Err(Degenerate::WallZeroArea { area });
        }
        let (width, height) = (self.u.length(), self.v.length());
        let tol = CONTACT_EPS;
        for (index, o) in self.openings.iter().enumerate() {
            if ![o.s0, o.t0, o.s1, o.t1].iter().all(|x| x.is_finite()) {
                return Err(Degenerate::OpeningNotFinite { index });
            }
            if o.s0 >= o.s1 || o.t0 >= o.t1 {
                return Err(Degenerate::OpeningEmpty { index });
            }
            if o.s0 < -tol || o.t0 < -tol || o.s1 > width + tol || o.t1 > height + tol {
                return Err(Degenerate::OpeningOutside {
                    index,
                    width,
                    height,
                });
            }
        }
        Ok(())
    }

    /// Whether the open segment from `a` to `b` crosses the solid part of the
    /// wall. Touching the wall's plane at an endpoint does not count, nor does a
    /// segment in the plane; crossing inside an opening does not count.
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        if !a.is_finite() || !b.is_finite() {
            return false;
        }
        if !self.origin.is_finite() || !self.u.is_finite() || !self.v.is_finite() {
            return false;
        }
        let n = self.normal();
        let nn = n.length_squared();
        let area = nn.sqrt();
        if area.is_nan() || area <= MIN_AREA {
            return false;
        }
        let inv_len = 1.0 / area;
        let da = (a - self.origin).dot(n) * inv_len;
        let db = (b - self.origin).dot(n) * inv_len;
        if da.abs() <= CONTACT_EPS || db.abs() <= CONTACT_EPS || (da > 0.0) == (db > 0.0) {
            return false;
        }
        let t = da / (da - db);
        let w = a + (b - a) * t - self.origin;
        let alpha = w.cross(self.v).dot(n) / nn;
        let beta = self.u.cross(w).dot(n) / nn;
        if !(0.0..=1.0).contains(&alpha) || !(0.0..=1.0).contains(&beta) {
            return false;
        }
        let s = alpha * self.u.length();
        let t = beta * self.v.length();
        !self.openings.iter().any(|o| o.admits(s, t))
    }
}

/// Something that blocks sound between a source and a receiver.
#[derive(Debug, Clone, PartialEq)]
pub enum Obstacle {
    /// An axis-aligned box (a cabinet).
    Box(AlignedBox),
    /// A thin wall, possibly with openings.
    Wall(Wall),
}

impl Obstacle {
    /// Whether the open segment from `a` to `b` is blocked by this obstacle
    /// (see [`AlignedBox::segment_blocked`] and [`Wall::segment_blocked`]).
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        match self {
            Obstacle::Box(b_) => b_.segment_blocked(a, b),
            Obstacle::Wall(w) => w.segment_blocked(a, b),
        }
    }

    /// Whether `p` is strictly inside the obstacle; always false for a wall,
    /// which has no inside.
    pub fn contains(&self, p: DVec3) -> bool {
        match self {
            Obstacle::Box(b) => b.contains(p),
            Obstacle::Wall(_) => false,
        }
    }

    /// Why the obstacle is degenerate, if it is.
    pub fn validate(&self) -> Result<(), Degenerate> {
        match self {
            Obstacle::Box(b) => b.validate(),
            Obstacle::Wall(w) => w.validate(),
        }
    }
}

impl From<AlignedBox> for Obstacle {
    fn from(b: AlignedBox) -> Self {
        Obstacle::Box(b)
    }
}

impl From<Wall> for Obstacle {
    fn from(w: Wall) -> Self {
        Obstacle::Wall(w)
    }
}

/// Index of the first obstacle (in slice order) blocking the open segment from
/// `a` to `b`, or `None` when the segment is clear.
pub fn first_blocking(obstacles: &[Obstacle], a: DVec3, b: DVec3) -> Option<usize> {
    obstacles.iter().position(|o| o.segment_blocked(a, b))
}

// ---------------------------------------------------------------------------
// Shoebox room and image sources
// ---------------------------------------------------------------------------

/// Index of the wall at `x = min.x` in a [`Room`].
pub const WALL_X_MIN: usize = 0;
/// Index of the wall at `x = max.x`.
pub const WALL_X_MAX: usize = 1;
/// Index of the wall at `y = min.y`.
pub const WALL_Y_MIN: usize = 2;
/// Index of the wall at `y = max.y`.
pub const WALL_Y_MAX: usize = 3;
/// Index of the floor, `z = min.z`.
pub const FLOOR: usize = 4;
/// Index of the ceiling, `z = max.z`.
pub const CEILING: usize = 5;

/// A shoebox room: the axis-aligned box from `min` to `max` (metres), whose
/// six faces reflect sound. Walls are indexed `2·axis + side`: 0 x−, 1 x+,
/// 2 y−, 3 y+, 4 floor (z−), 5 ceiling (z+) — see [`WALL_X_MIN`] and friends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Room {
    /// The corner with the smallest coordinates, metres.
    pub min: DVec3,
    /// The corner with the largest coordinates, metres.
    pub max: DVec3,
}

/// A mirror image of a source in a [`Room`]'s walls: sound reflected off
/// `walls` arrives at any receiver in the room as if straight from `position`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageSource {
    /// Where the image is, metres (outside the room).
    pub position: DVec3,
    /// The real source it mirrors, metres.
    pub source: DVec3,
    /// The image's cell in the Allen & Berkley lattice: how many times (and in
    /// which direction) the path is mirrored along x, y and z.
    pub index: [i32; 3],
    /// Number of reflections, `|index|` summed; 1..=[`MAX_ORDER`].
    pub order: usize,
    /// The walls hit, in path order for a receiver at the source itself; the
    /// first `order` entries are meaningful. For images mirrored along more than
    /// one axis the interleaving depends on the receiver: use
    /// [`Room::reflection_path`] for the order along a given path.
    pub walls: [usize; MAX_ORDER],
}

impl ImageSource {
    /// The walls hit (see [`ImageSource::walls`]).
    pub fn walls(&self) -> &[usize] {
        &self.walls[..self.order.min(MAX_ORDER)]
    }
}

/// One reflected path from a source to a receiver, with no allocation: the
/// reflection points in order from the source, and the wall of each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReflectionPath {
    /// The real source, metres.
    pub source: DVec3,
    /// The receiver, metres.
    pub receiver: DVec3,
    /// Reflection points on the walls, source side first; first `len` valid.
    pub points: [DVec3; MAX_ORDER],
    /// The wall of each reflection point; first `len` valid.
    pub walls: [usize; MAX_ORDER],
    /// Number of reflections.
    pub len: usize,
    /// Total path length, metres: the distance from the image to the receiver,
    /// equal to the sum of the legs.
    pub length: f64,
}

impl ReflectionPath {
    /// The reflection points, source side first.
    pub fn points(&self) -> &[DVec3] {
        &self.points[..self.len]
    }

    /// The wall of each reflection point.
    pub fn walls(&self) -> &[usize] {
        &self.walls[..self.len]
    }

    /// The straight legs of the path, source → first reflection → … → receiver
    /// (`len + 1` of them), each to be tested against the obstacles.
    pub fn legs(&self) -> impl Iterator<Item = (DVec3, DVec3)> + '_ {
        let n = self.len;
        (0..=n).map(move |i| {
            let a = if i == 0 {
                self.source
            } else {
                self.points[i - 1]
            };
            let b = if i == n {
                self.receiver
            } else {
                self.points[i]
            };
            (a, b)
        })
    }
}

/// One plane crossing of an unfolded path: parameter along it, axis and the
/// lattice plane number `m` (the plane is at `min + m·size` along the axis).
#[derive(Clone, Copy)]
struct Crossing {
    t: f64,
    axis: usize,
    m: i32,
}

impl Room {
    /// The room between two corners (taken in any order), metres.
    pub fn new(a: DVec3, b: DVec3) -> Self {
        Self {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// A room of the given size with its `min` corner at the origin, metres.
    pub fn from_size(size: DVec3) -> Self {
        Self::new(DVec3::ZERO, size)
    }

    /// The size along x, y and z, metres.
    pub fn size(&self) -> DVec3 {
        self.max - self.min
    }

    /// Why the room is degenerate, if it is.
    pub fn validate(&self) -> Result<(), Degenerate> {
        if !self.min.is_finite() || !self.max.is_finite() {
            return Err(Degenerate::RoomNotFinite);
        }
        let size = self.size();
        if size.min_element() <= 0.0 {
            return Err(Degenerate::RoomZeroSize { size });
        }
        Ok(())
    }

    /// Whether `p` is inside the room or on its walls.
    pub fn contains(&self, p: DVec3) -> bool {
        self.validate().is_ok() && p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// Whether `p` lies on wall `wall` (within [`CONTACT_EPS`]); false for a
    /// wall index above 5.
    pub fn on_wall(&self, wall: usize, p: DVec3) -> bool {
        if wall >= 6 || self.validate().is_err() || !p.is_finite() {
            return false;
        }
        let axis = wall / 2;
        let plane = if wall.is_multiple_of(2) {
            self.min[axis]
        } else {
            self.max[axis]
        };
        if (p[axis] - plane).abs() > CONTACT_EPS {
            return false;
        }
        (0..3)
            .filter(|&a| a != axis)
            .all(|a| p[a] >= self.min[a] - CONTACT_EPS && p[a] <= self.max[a] + CONTACT_EPS)
    }

    /// The image sources of `source` up to `max_order` reflections (clamped to
    /// [`MAX_ORDER`]), without the direct path: 6 of order 1, 18 of order 2,
    /// `4k² + 2` of order k. Empty when the room is degenerate or the source
    /// is not in the room.
    pub fn image_sources(&self, source: DVec3, max_order: usize) -> Vec<ImageSource> {
        let mut out = Vec::new();
        self.image_sources_into(source, max_order, &mut out);
        out
    }

    /// [`Room::image_sources`] into a reused buffer (cleared first), so a moving
    /// source needs no allocation once the buffer has grown. The order is
    /// deterministic: by order, then by lattice index.
    pub fn image_sources_into(&self, source: DVec3, max_order: usize, out: &mut Vec<ImageSource>) {
        out.clear();
        if !self.contains(source) {
            return;
        }
        let max_order = max_order.min(MAX_ORDER) as i32;
        for k in 1..=max_order {
            for ix in -k..=k {
                let rest = k - ix.abs();
                for iy in -rest..=rest {
                    let rz = rest - iy.abs();
                    let zs: &[i32] = if rz == 0 { &[0] } else { &[-rz, rz] };
                    for &iz in zs {
                        out.push(self.image(source, [ix, iy, iz]));
                    }
                }
            }
        }
    }

    /// The image of `source` in lattice cell `index` (see [`ImageSource::index`]).
    fn image(&self, source: DVec3, index: [i32; 3]) -> ImageSource {
        let size = self.size();
        let mut position = DVec3::ZERO;
        for axis in 0..3 {
            let n = index[axis] as f64;
            let rel = source[axis] - self.min[axis];
            let l = size[axis];
            position[axis] = self.min[axis]
                + if index[axis] % 2 == 0 {
                    rel + n * l
                } else {
                    (n + 1.0) * l - rel
                };
        }
        let order = index.iter().map(|i| i.unsigned_abs() as usize).sum();
        let mut image = ImageSource {
            position,
            source,
            index,
            order,
            walls: [0; MAX_ORDER],
        };
        let mut crossings = [Crossing {
            t: 0.0,
            axis: 0,
            m: 0,
        }; MAX_ORDER];
        let n = self.crossings(&image, source, &mut crossings);
        for (w, c) in image.walls.iter_mut().zip(&crossings[..n]) {
            *w = 2 * c.axis + c.m.rem_euclid(2) as usize;
        }
        image
    }

    /// The lattice planes crossed by the unfolded straight line from the image
    /// to `target`, sorted from the image side (that is, in path order from the
    /// source). Returns how many; ties keep axis order. A line running within a
    /// plane gets t = 0 for it (callers that need a real path reject those).
    fn crossings(
        &self,
        image: &ImageSource,
        target: DVec3,
        out: &mut [Crossing; MAX_ORDER],
    ) -> usize {
        let size = self.size();
        let mut n = 0;
        for axis in 0..3 {
            let k = image.index[axis];
            let denom = target[axis] - image.position[axis];
            // Planes from the image side towards cell 0: k, k−1, …, 1 for a
            // positive index, k+1, k+2, …, 0 for a negative one.
            let count = (k.unsigned_abs() as usize).min(MAX_ORDER);
            for j in 0..count as i32 {
                if n == MAX_ORDER {
                    return n;
                }
                let m = if k > 0 { k - j } else { k + 1 + j };
                let plane = self.min[axis] + m as f64 * size[axis];
                let t = if denom == 0.0 {
                    0.0
                } else {
                    (plane - image.position[axis]) / denom
                };
                // Insertion keeping the array sorted by t, stable for ties.
                let mut j = n;
                while j > 0 && out[j - 1].t > t {
                    out[j] = out[j - 1];
                    j -= 1;
                }
                out[j] = Crossing { t, axis, m };
                n += 1;
            }
        }
        n
    }

    /// The reflected path of `image` to `receiver`: the reflection points on
    /// the walls in order from the source, found by intersecting the unfolded
    /// segment from image to receiver with the lattice planes and folding each
    /// crossing back into the room. `None` when the path is invalid: degenerate
    /// room, receiver outside the room, an image not of this room or of order
    /// above [`MAX_ORDER`], a path grazing along a wall, or a reflection point
    /// off its wall. Allocation-free.
    pub fn reflection_path(&self, image: &ImageSource, receiver: DVec3) -> Option<ReflectionPath> {
        if !self.contains(receiver) || !self.contains(image.source) || !image.position.is_finite() {
            return None;
        }
        let order: usize = image.index.iter().map(|i| i.unsigned_abs() as usize).sum();
        if order != image.order || order == 0 || order > MAX_ORDER {
            return None;
        }
        let mut crossings = [Crossing {
            t: 0.0,
            axis: 0,
            m: 0,
        }; MAX_ORDER];
        let n = self.crossings(image, receiver, &mut crossings);
        if n != order {
            return None;
        }
        let mut path = ReflectionPath {
            source: image.source,
            receiver,
            points: [DVec3::ZERO; MAX_ORDER],
            walls: [0; MAX_ORDER],
            len: n,
            length: image.position.distance(receiver),
        };
        let d = receiver - image.position;
        let size = self.size();
        let tol = CONTACT_EPS / d.length().max(CONTACT_EPS);
        for (i, c) in crossings[..n].iter().enumerate() {
            if d[c.axis] == 0.0 || !(c.t >= -tol && c.t <= 1.0 + tol) {
                return None;
            }
            let wall = 2 * c.axis + c.m.rem_euclid(2) as usize;
            let unfolded = image.position + d * c.t;
            let mut p = DVec3::ZERO;
            for axis in 0..3 {
                p[axis] = if axis == c.axis {
                    if wall.is_multiple_of(2) {
                        self.min[axis]
                    } else {
                        self.max[axis]
                    }
                } else {
                    fold(unfolded[axis], self.min[axis], size[axis])
                };
            }
            if !self.on_wall(wall, p) {
                return None;
            }
            path.points[i] = p;
            path.walls[i] = wall;
        }
        Some(path)
    }
}

/// Folds an unfolded lattice coordinate back into `[lo, lo + size]`.
fn fold(x: f64, lo: f64, size: f64) -> f64 {
    let period = 2.0 * size;
    let mut y = (x - lo).rem_euclid(period);
    if y > size {
        y = period - y;
    }
    lo + y
}

// ---------------------------------------------------------------------------
// Classification (Table 1)
// ---------------------------------------------------------------------------

/// The obstacle effect on a source–receiver pair (Table 1 of the paper).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Condition {
    /// Direct sound and reflections reach the receiver: no effect.
    Free,
    /// Direct sound and reflections are blocked (source and receiver in
    /// different rooms): everything is muffled.
    Occlusion,
    /// Direct sound blocked but reflections reach (a cabinet in between): the
    /// direct sound is muffled, the reverberation is not.
    Obstruction,
    /// Direct sound reaches but reflections do not (through an open window):
    /// the reverberation is muffled, the direct sound is not.
    Exclusion,
}

/// What [`classify`] found for one source–receiver pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PathReport {
    /// Index of the first obstacle (in slice order) blocking the direct path.
    pub direct_blocked_by: Option<usize>,
    /// Reflected paths considered (all images passed in, any order).
    pub reflections_total: usize,
    /// Of those, the ones whose every leg is clear.
    pub reflections_reaching: usize,
    /// First-order reflected paths considered.
    pub first_order_total: usize,
    /// Of those, the ones whose every leg is clear.
    pub first_order_reaching: usize,
    /// The resulting condition.
    pub condition: Condition,
}

/// Whether the reflected path of `image` to `receiver` is blocked: true when
/// any leg is blocked by any obstacle, and when the path is invalid (see
/// [`Room::reflection_path`]), since then no sound arrives along it. The
/// caller attenuates blocked reflections individually.
pub fn reflection_blocked(
    room: &Room,
    image: &ImageSource,
    receiver: DVec3,
    obstacles: &[Obstacle],
) -> bool {
    match room.reflection_path(image, receiver) {
        None => true,
        Some(path) => path
            .legs()
            .any(|(a, b)| first_blocking(obstacles, a, b).is_some()),
    }
}

/// Classifies a source–receiver pair per Table 1; see [`classify_with`], which
/// also reports each image's path.
pub fn classify(
    source: DVec3,
    receiver: DVec3,
    obstacles: &[Obstacle],
    room: Option<&Room>,
    images: &[ImageSource],
) -> PathReport {
    classify_with(source, receiver, obstacles, room, images, |_, _| {})
}

/// Classifies a source–receiver pair per Table 1 and calls
/// `on_image(i, blocked)` for each image `images[i]`, so the caller can
/// attenuate blocked reflections individually. No allocation.
///
/// The direct path is the segment from `source` to `receiver`. `images` must
/// be the image sources of `source` in `room` (any orders).
///
/// Reflections **reach** when at least half of the first-order reflected paths
/// are unblocked (with no first-order image given, half of all the images
/// given). The threshold follows the paper's wording: exclusion is when "most
/// reflected sound cannot" reach.
///
/// With no room (or no images) there are no reflected paths: a blocked direct
/// path is then [`Condition::Obstruction`] (in open air sound bends around the
/// obstacle) and a clear one [`Condition::Free`]. Images given without a room
/// are ignored.
pub fn classify_with(
    source: DVec3,
    receiver: DVec3,
    obstacles: &[Obstacle],
    room: Option<&Room>,
    images: &[ImageSource],
    mut on_image: impl FnMut(usize, bool),
) -> PathReport {
    let direct_blocked_by = first_blocking(obstacles, source, receiver);
    let (mut total, mut reaching, mut first_total, mut first_reaching) = (0, 0, 0, 0);
    if let Some(room) = room {
        for (i, image) in images.iter().enumerate() {
            let blocked = reflection_blocked(room, image, receiver, obstacles);
            on_image(i, blocked);
            total += 1;
            reaching += usize::from(!blocked);
            if image.order == 1 {
                first_total += 1;
                first_reaching += usize::from(!blocked);
            }
        }
    }
    let (t, r) = if first_total > 0 {
        (first_total, first_reaching)
    } else {
        (total, reaching)
    };
    let direct = direct_blocked_by.is_none();
    let condition = if t == 0 {
        if direct {
            Condition::Free
        } else {
            Condition::Obstruction
        }
    } else {
        let reflections = 2 * r >= t;
        match (direct, reflections) {
            (true, true) => Condition::Free,
            (false, false) => Condition::Occlusion,
            (false, true) => Condition::Obstruction,
            (true, false) => Condition::Exclusion,
        }
    };
    PathReport {
        direct_blocked_by,
        reflections_total: total,
        reflections_reaching: reaching,
        first_order_total: first_total,
        first_order_reaching: first_reaching,
        condition,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    fn unit_box() -> AlignedBox {
        AlignedBox::new(v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0))
    }

    #[test]
    fn box_hits_and_misses() {
        let b = unit_box();
        assert!(b.segment_blocked(v(-3.0, 0.0, 0.0), v(3.0, 0.0, 0.0)));
        assert!(b.segment_blocked(v(-3.0, -3.0, -3.0), v(3.0, 3.0, 3.0)));
        // Beside, above, short of the box.
        assert!(!b.segment_blocked(v(-3.0, 1.5, 0.0), v(3.0, 1.5, 0.0)));
        assert!(!b.segment_blocked(v(0.0, 0.0, 1.01), v(0.0, 5.0, 1.01)));
        assert!(!b.segment_blocked(v(-3.0, 0.0, 0.0), v(-1.5, 0.0, 0.0)));
        // Diagonals passing outside and inside a corner.
        assert!(!b.segment_blocked(v(0.0, 2.1, 0.0), v(2.1, 0.0, 0.0)));
        assert!(b.segment_blocked(v(0.0, 1.9, 0.0), v(1.9, 0.0, 0.0)));
        // Direction reversed gives the same answer.
        assert!(b.segment_blocked(v(3.0, 0.0, 0.0), v(-3.0, 0.0, 0.0)));
    }

    #[test]
    fn box_grazing_and_endpoints() {
        let b = unit_box();
        // Grazing along a face: the box is closed, its surface blocks.
        assert!(b.segment_blocked(v(-3.0, 1.0, 0.0), v(3.0, 1.0, 0.0)));
        // Grazing an edge at a single point (x + y = 2 meets the corner
        // (1, 1)), and passing beyond it (x + y = 3).
        assert!(!b.segment_blocked(v(0.0, 3.0, 0.0), v(3.0, 0.0, 0.0)));
        assert!(b.segment_blocked(v(-1.0, 3.0, 0.0), v(3.0, -1.0, 0.0)));
        // Just outside the face: clear.
        assert!(!b.segment_blocked(v(-3.0, 1.0 + 1e-7, 0.0), v(3.0, 1.0 + 1e-7, 0.0)));
        // Endpoint on the face, pointing away: touching does not count.
        assert!(!b.segment_blocked(v(1.0, 0.0, 0.0), v(4.0, 0.0, 0.0)));
        assert!(!b.segment_blocked(v(4.0, 0.0, 0.0), v(1.0, 0.0, 0.0)));
        assert!(!b.segment_blocked(v(0.0, 0.0, 1.0), v(0.0, 0.0, 5.0)));
        // Endpoint on the face, pointing in: it crosses the solid.
        assert!(b.segment_blocked(v(1.0, 0.0, 0.0), v(-4.0, 0.0, 0.0)));
        // Endpoint inside: blocked (a source inside a cabinet).
        assert!(b.segment_blocked(v(0.5, 0.0, 0.0), v(4.0, 0.0, 0.0)));
        assert!(b.segment_blocked(v(0.1, 0.2, 0.3), v(-0.1, 0.0, 0.1)));
        // Zero-length segments block nothing, even inside.
        assert!(!b.segment_blocked(v(0.5, 0.0, 0.0), v(0.5, 0.0, 0.0)));
    }

    #[test]
    fn box_contains_and_moves() {
        let mut b = AlignedBox::from_corners(v(2.0, 1.0, 0.0), v(0.0, 0.0, 3.0));
        assert_eq!(b.centre, v(1.0, 0.5, 1.5));
        assert!(b.contains(v(1.0, 0.5, 1.0)));
        assert!(!b.contains(v(2.0, 0.5, 1.0)), "surface is not inside");
        assert!(!b.contains(v(3.0, 0.5, 1.0)));
        b.centre = v(10.0, 0.5, 1.5);
        assert!(!b.contains(v(1.0, 0.5, 1.0)));
        assert!(b.contains(v(10.0, 0.5, 1.0)));
        assert!(b.segment_blocked(v(10.0, -5.0, 1.0), v(10.0, 5.0, 1.0)));
        assert!(!b.segment_blocked(v(1.0, -5.0, 1.0), v(1.0, 5.0, 1.0)));
    }

    #[test]
    fn degenerate_boxes_block_nothing() {
        let flat = AlignedBox::new(DVec3::ZERO, v(1.0, 0.0, 1.0));
        assert!(matches!(
            flat.validate(),
            Err(Degenerate::BoxZeroSize { .. })
        ));
        assert!(!flat.segment_blocked(v(0.0, -1.0, 0.0), v(0.0, 1.0, 0.0)));
        assert!(!flat.contains(DVec3::ZERO));
        let nan = AlignedBox::new(v(f64::NAN, 0.0, 0.0), DVec3::ONE);
        assert_eq!(nan.validate(), Err(Degenerate::BoxNotFinite));
        assert!(!nan.segment_blocked(v(-3.0, 0.0, 0.0), v(3.0, 0.0, 0.0)));
        let b = unit_box();
        assert!(b.validate().is_ok());
        assert!(!b.segment_blocked(v(f64::NAN, 0.0, 0.0), v(3.0, 0.0, 0.0)));
        assert!(!b.segment_blocked(v(f64::INFINITY, 0.0, 0.0), v(-3.0, 0.0, 0.0)));
        assert!(!b.contains(v(f64::NAN, 0.0, 0.0)));
    }

    /// A wall in the plane x = 5, 5 m along y and 3 m up.
    fn dividing_wall() -> Wall {
        Wall::new(v(5.0, 0.0, 0.0), v(0.0, 5.0, 0.0), v(0.0, 0.0, 3.0))
    }

    #[test]
    fn wall_hits_misses_and_window() {
        let w = dividing_wall();
        assert!(w.validate().is_ok());
        assert!(w.segment_blocked(v(2.0, 2.0, 1.0), v(8.0, 3.0, 1.5)));
        assert!(w.segment_blocked(v(8.0, 3.0, 1.5), v(2.0, 2.0, 1.0)));
        // Over the top, past the end, not reaching it.
        assert!(!w.segment_blocked(v(2.0, 2.0, 3.5), v(8.0, 2.0, 3.5)));
        assert!(!w.segment_blocked(v(2.0, 6.0, 1.0), v(8.0, 6.0, 1.0)));
        assert!(!w.segment_blocked(v(2.0, 2.0, 1.0), v(4.9, 2.0, 1.0)));
        // Endpoint on the wall does not count; lying in the plane does not either.
        assert!(!w.segment_blocked(v(5.0, 2.0, 1.0), v(8.0, 2.0, 1.0)));
        assert!(!w.segment_blocked(v(5.0, 1.0, 1.0), v(5.0, 4.0, 2.0)));
        // Edges are solid.
        assert!(w.segment_blocked(v(2.0, 5.0, 1.0), v(8.0, 5.0, 1.0)));

        let window = dividing_wall().with_opening(Opening::new(1.5, 0.8, 3.5, 2.2));
        assert!(window.validate().is_ok());
        // Through the window.
        assert!(!window.segment_blocked(v(2.0, 2.5, 1.5), v(8.0, 2.5, 1.5)));
        assert!(!window.segment_blocked(v(2.0, 2.0, 1.6), v(8.0, 3.0, 1.2)));
        // Beside, below and above it.
        assert!(window.segment_blocked(v(2.0, 1.0, 1.5), v(8.0, 1.0, 1.5)));
        assert!(window.segment_blocked(v(2.0, 4.0, 1.5), v(8.0, 4.0, 1.5)));
        assert!(window.segment_blocked(v(2.0, 2.5, 0.5), v(8.0, 2.5, 0.5)));
        assert!(window.segment_blocked(v(2.0, 2.5, 2.5), v(8.0, 2.5, 2.5)));
        // Slanted: enters the window's plane outside it.
        assert!(window.segment_blocked(v(2.0, 2.5, 1.5), v(8.0, 6.5, 1.5)));
    }

    #[test]
    fn slanted_wall_coordinates() {
        // A wall along the diagonal of the xy plane, u not axis-aligned.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let w = Wall::new(DVec3::ZERO, v(4.0 * s, 4.0 * s, 0.0), v(0.0, 0.0, 2.0))
            .with_opening(Opening::new(1.0, 0.5, 2.0, 1.5));
        // Crossing at 1.5 m along u, 1 m up: in the opening.
        let p = v(1.5 * s, 1.5 * s, 1.0);
        let n = v(s, -s, 0.0);
        assert!(!w.segment_blocked(p + n, p - n));
        // At 3 m along u: solid.
        let q = v(3.0 * s, 3.0 * s, 1.0);
        assert!(w.segment_blocked(q + n, q - n));
        // At 4.5 m along u: past the wall.
        let r = v(4.5 * s, 4.5 * s, 1.0);
        assert!(!w.segment_blocked(r + n, r - n));
    }

    #[test]
    fn wall_validation() {
        let zero = Wall::new(DVec3::ZERO, v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0));
        assert!(matches!(
            zero.validate(),
            Err(Degenerate::WallZeroArea { .. })
        ));
        assert!(!zero.segment_blocked(v(0.5, -1.0, 0.0), v(0.5, 1.0, 0.0)));
        let outside = dividing_wall().with_opening(Opening::new(4.0, 1.0, 6.0, 2.0));
        assert!(matches!(
            outside.validate(),
            Err(Degenerate::OpeningOutside { index: 0, .. })
        ));
        let empty = dividing_wall()
            .with_opening(Opening::new(1.0, 1.0, 2.0, 2.0))
            .with_opening(Opening::new(3.0, 1.0, 2.0, 2.0));
        assert_eq!(empty.validate(), Err(Degenerate::OpeningEmpty { index: 1 }));
        let nan = Wall::new(DVec3::ZERO, v(f64::NAN, 0.0, 0.0), v(0.0, 0.0, 1.0));
        assert_eq!(nan.validate(), Err(Degenerate::WallNotFinite));
        assert!(!nan.segment_blocked(v(0.0, -1.0, 0.5), v(0.0, 1.0, 0.5)));
        // Messages are usable as diagnostics.
        assert!(Degenerate::OpeningEmpty { index: 1 }
            .to_string()
            .contains("opening 1"));
    }

    #[test]
    fn first_blocking_reports_index() {
        let obstacles = [
            Obstacle::from(AlignedBox::new(v(0.0, 10.0, 0.0), DVec3::ONE)),
            Obstacle::from(dividing_wall()),
            Obstacle::from(AlignedBox::new(v(7.0, 2.0, 1.0), DVec3::splat(0.5))),
        ];
        assert_eq!(
            first_blocking(&obstacles, v(2.0, 2.0, 1.0), v(8.0, 2.0, 1.0)),
            Some(1)
        );
        assert_eq!(
            first_blocking(&obstacles, v(6.0, 2.0, 1.0), v(8.0, 2.0, 1.0)),
            Some(2)
        );
        assert_eq!(
            first_blocking(&obstacles, v(6.0, 4.0, 1.0), v(8.0, 4.0, 1.0)),
            None
        );
        assert!(obstacles[2].contains(v(7.0, 2.0, 1.0)));
        assert!(!obstacles[1].contains(v(5.0, 2.0, 1.0)));
    }

    fn room() -> Room {
        Room::new(v(1.0, 2.0, 0.0), v(5.0, 5.0, 3.0))
    }

    #[test]
    fn room_contains_and_validates() {
        let r = room();
        assert!(r.validate().is_ok());
        assert!(r.contains(v(2.0, 3.0, 1.0)));
        assert!(r.contains(v(1.0, 3.0, 0.0)), "walls are inside");
        assert!(!r.contains(v(0.9, 3.0, 1.0)));
        assert_eq!(Room::new(v(5.0, 5.0, 3.0), v(1.0, 2.0, 0.0)), r);
        assert_eq!(Room::from_size(v(4.0, 3.0, 3.0)).min, DVec3::ZERO);
        let flat = Room::new(DVec3::ZERO, v(4.0, 3.0, 0.0));
        assert!(matches!(
            flat.validate(),
            Err(Degenerate::RoomZeroSize { .. })
        ));
        assert!(flat.image_sources(v(1.0, 1.0, 0.0), 2).is_empty());
        let nan = Room::new(DVec3::ZERO, v(f64::NAN, 1.0, 1.0));
        assert!(nan.validate().is_err());
        assert!(!nan.contains(DVec3::ZERO));
    }

    #[test]
    fn first_order_images_are_mirrors() {
        let r = room();
        let s = v(2.0, 3.5, 1.2);
        let images = r.image_sources(s, 1);
        assert_eq!(images.len(), 6);
        let expect = [
            (WALL_X_MIN, v(0.0, 3.5, 1.2)),
            (WALL_X_MAX, v(8.0, 3.5, 1.2)),
            (WALL_Y_MIN, v(2.0, 0.5, 1.2)),
            (WALL_Y_MAX, v(2.0, 6.5, 1.2)),
            (FLOOR, v(2.0, 3.5, -1.2)),
            (CEILING, v(2.0, 3.5, 4.8)),
        ];
        for (wall, pos) in expect {
            let found: Vec<_> = images.iter().filter(|i| i.walls() == [wall]).collect();
            assert_eq!(found.len(), 1, "one image for wall {wall}");
            assert!(
                found[0].position.distance(pos) < 1e-12,
                "wall {wall}: {:?}",
                found[0].position
            );
            assert_eq!(found[0].order, 1);
            assert_eq!(found[0].source, s);
        }
        // A source outside the room has no images.
        assert!(r.image_sources(v(0.0, 3.0, 1.0), 2).is_empty());
    }

    #[test]
    fn second_order_images() {
        let r = room();
        let s = v(2.0, 3.5, 1.2);
        let images = r.image_sources(s, DEFAULT_ORDER);
        assert_eq!(images.len(), 24);
        assert_eq!(images.iter().filter(|i| i.order == 2).count(), 18);
        // Distinct positions (no duplicates).
        for (i, a) in images.iter().enumerate() {
            for b in &images[i + 1..] {
                assert!(a.position.distance(b.position) > 1e-9);
            }
        }
        let find = |walls: &[usize]| -> DVec3 {
            let f: Vec<_> = images.iter().filter(|i| i.walls() == walls).collect();
            assert_eq!(f.len(), 1, "{walls:?}");
            f[0].position
        };
        // x− then x+: mirror in x = 1 (→ 0), then in x = 5 (→ 10).
        assert!(find(&[WALL_X_MIN, WALL_X_MAX]).distance(v(10.0, 3.5, 1.2)) < 1e-12);
        // x+ then x−: mirror in x = 5 (→ 8), then in x = 1 (→ −6).
        assert!(find(&[WALL_X_MAX, WALL_X_MIN]).distance(v(-6.0, 3.5, 1.2)) < 1e-12);
        assert!(find(&[FLOOR, CEILING]).distance(v(2.0, 3.5, 7.2)) < 1e-12);
        assert!(find(&[CEILING, FLOOR]).distance(v(2.0, 3.5, -4.8)) < 1e-12);
        // Corner images: both mirrors applied.
        let corner: Vec<_> = images.iter().filter(|i| i.index == [-1, 0, -1]).collect();
        assert_eq!(corner.len(), 1);
        assert!(corner[0].position.distance(v(0.0, 3.5, -1.2)) < 1e-12);
        let mut walls = corner[0].walls().to_vec();
        walls.sort();
        assert_eq!(walls, [WALL_X_MIN, FLOOR]);
        // Higher orders: 4k² + 2 each; clamped at MAX_ORDER.
        assert_eq!(r.image_sources(s, 3).len(), 24 + 38);
        let all = r.image_sources(s, 100);
        assert_eq!(
            all.len(),
            (1..=MAX_ORDER).map(|k| 4 * k * k + 2).sum::<usize>()
        );
        // The reusing form gives the same list.
        let mut buf = Vec::new();
        r.image_sources_into(s, 2, &mut buf);
        assert_eq!(buf, images);
    }

    #[test]
    fn reflection_paths_lie_on_walls_and_unfold() {
        let r = room();
        let s = v(2.0, 3.5, 1.2);
        let rx = v(4.3, 2.6, 1.7);
        let images = r.image_sources(s, 4);
        for image in &images {
            let path = r.reflection_path(image, rx).expect("valid path");
            assert_eq!(path.len, image.order);
            let mut walls = path.walls().to_vec();
            let mut expect = image.walls().to_vec();
            walls.sort();
            expect.sort();
            assert_eq!(walls, expect, "same walls, maybe interleaved differently");
            for (p, &w) in path.points().iter().zip(path.walls()) {
                assert!(r.on_wall(w, *p), "{p:?} off wall {w}");
            }
            let legs: f64 = path.legs().map(|(a, b)| a.distance(b)).sum();
            assert_eq!(path.legs().count(), image.order + 1);
            assert!(
                (legs - path.length).abs() < 1e-9,
                "{legs} vs {}",
                path.length
            );
            assert!((path.length - image.position.distance(rx)).abs() < 1e-12);
            // Each reflection is specular: consecutive legs make equal angles
            // with the wall's normal.
            let pts: Vec<_> = path.legs().collect();
            for (k, &w) in path.walls().iter().enumerate() {
                let axis = w / 2;
                let (a, b) = (pts[k].1 - pts[k].0, pts[k + 1].1 - pts[k + 1].0);
                let (a, b) = (a.normalize(), b.normalize());
                assert!((a[axis] + b[axis]).abs() < 1e-9);
                for o in (0..3).filter(|&o| o != axis) {
                    assert!((a[o] - b[o]).abs() < 1e-9);
                }
            }
        }
        // A first-order floor reflection, by hand: image at z = −1.2,
        // receiver at z = 1.7, crossing z = 0 at 1.2/2.9 of the way.
        let floor = images.iter().find(|i| i.walls() == [FLOOR]).unwrap();
        let path = r.reflection_path(floor, rx).unwrap();
        let f = 1.2 / 2.9;
        let expect = v(2.0 + 2.3 * f, 3.5 - 0.9 * f, 0.0);
        assert!(path.points[0].distance(expect) < 1e-12);
        assert_eq!(path.points[0].z, 0.0, "snapped exactly onto the floor");
    }

    #[test]
    fn invalid_reflection_paths() {
        let r = room();
        let s = v(2.0, 3.5, 1.2);
        let image = r.image_sources(s, 1)[0];
        // Receiver outside the room.
        assert!(r.reflection_path(&image, v(0.0, 3.0, 1.0)).is_none());
        // An image of another room, or a tampered one.
        let other = Room::new(DVec3::ZERO, v(40.0, 40.0, 40.0));
        let foreign = other.image_sources(v(20.0, 20.0, 20.0), 1)[0];
        assert!(r.reflection_path(&foreign, v(2.0, 3.0, 1.0)).is_none());
        let mut bad = image;
        bad.order = 3;
        assert!(r.reflection_path(&bad, v(2.0, 3.0, 1.0)).is_none());
        let mut nan = image;
        nan.position.x = f64::NAN;
        assert!(r.reflection_path(&nan, v(2.0, 3.0, 1.0)).is_none());
        // Invalid paths count as blocked.
        assert!(reflection_blocked(&r, &image, v(0.0, 3.0, 1.0), &[]));
        assert!(!reflection_blocked(&r, &image, v(2.0, 3.0, 1.0), &[]));
    }

    /// Fig. 4 (a) and (b): a 10 × 5 × 3 m room divided by a wall at x = 5.
    fn divided(window: bool) -> (Room, Vec<Obstacle>) {
        let mut wall = dividing_wall();
        if window {
            wall = wall.with_opening(Opening::new(1.5, 0.8, 3.5, 2.2));
        }
        (Room::from_size(v(10.0, 5.0, 3.0)), vec![wall.into()])
    }

    const SOURCE: DVec3 = DVec3::new(2.0, 2.0, 1.6);
    const RECEIVER: DVec3 = DVec3::new(8.0, 3.0, 1.2);

    #[test]
    fn fig4a_occlusion() {
        let (room, obstacles) = divided(false);
        let images = room.image_sources(SOURCE, DEFAULT_ORDER);
        let report = classify(SOURCE, RECEIVER, &obstacles, Some(&room), &images);
        assert_eq!(report.direct_blocked_by, Some(0));
        assert_eq!(report.first_order_total, 6);
        assert_eq!(report.first_order_reaching, 0);
        assert_eq!(report.reflections_total, 24);
        assert_eq!(report.condition, Condition::Occlusion);
    }

    #[test]
    fn fig4b_exclusion() {
        let (room, obstacles) = divided(true);
        let images = room.image_sources(SOURCE, DEFAULT_ORDER);
        let mut blocked = vec![None; images.len()];
        let report = classify_with(
            SOURCE,
            RECEIVER,
            &obstacles,
            Some(&room),
            &images,
            |i, b| blocked[i] = Some(b),
        );
        assert_eq!(report.direct_blocked_by, None);
        // Only the end-wall reflections (x− and x+) pass the window; the side
        // walls, floor and ceiling paths hit the dividing wall.
        assert_eq!(report.first_order_total, 6);
        assert_eq!(report.first_order_reaching, 2);
        for (image, b) in images.iter().zip(&blocked) {
            if image.order == 1 {
                let end_wall = image.walls[0] == WALL_X_MIN || image.walls[0] == WALL_X_MAX;
                assert_eq!(*b, Some(!end_wall), "wall {}", image.walls[0]);
            }
        }
        assert_eq!(report.condition, Condition::Exclusion);
        assert!(blocked.iter().all(Option::is_some));
    }

    /// Fig. 4 (c): one 6 × 5 × 3 m room with a 2 m tall cabinet between
    /// source and receiver.
    fn cabinet_room() -> (Room, Vec<Obstacle>, DVec3, DVec3) {
        let cabinet = AlignedBox::new(v(3.0, 2.5, 1.0), v(0.4, 0.8, 1.0));
        (
            Room::from_size(v(6.0, 5.0, 3.0)),
            vec![cabinet.into()],
            v(1.0, 2.5, 1.2),
            v(5.0, 2.5, 1.2),
        )
    }

    #[test]
    fn fig4c_obstruction() {
        let (room, obstacles, s, r) = cabinet_room();
        let images = room.image_sources(s, DEFAULT_ORDER);
        let report = classify(s, r, &obstacles, Some(&room), &images);
        assert_eq!(report.direct_blocked_by, Some(0));
        // x− and x+ reflections run through the cabinet, the floor reflection
        // lands under it; the side walls and the ceiling go around it.
        assert_eq!(report.first_order_reaching, 3);
        assert_eq!(report.condition, Condition::Obstruction);
    }

    #[test]
    fn unobstructed_room_is_free() {
        let (room, _, s, r) = cabinet_room();
        let images = room.image_sources(s, DEFAULT_ORDER);
        let report = classify(s, r, &[], Some(&room), &images);
        assert_eq!(report.direct_blocked_by, None);
        assert_eq!(report.reflections_reaching, 24);
        assert_eq!(report.condition, Condition::Free);
        // A cabinet off to the side changes nothing for the direct path.
        let aside = [Obstacle::from(AlignedBox::new(
            v(3.0, 4.5, 0.5),
            v(0.3, 0.3, 0.5),
        ))];
        let report = classify(s, r, &aside, Some(&room), &images);
        assert_eq!(report.direct_blocked_by, None);
        assert_eq!(report.condition, Condition::Free);
    }

    #[test]
    fn open_air_rules() {
        let (_, obstacles, s, r) = cabinet_room();
        let report = classify(s, r, &obstacles, None, &[]);
        assert_eq!(report.condition, Condition::Obstruction);
        assert_eq!(report.reflections_total, 0);
        assert_eq!(classify(s, r, &[], None, &[]).condition, Condition::Free);
        // Images without a room are ignored.
        let room = Room::from_size(v(6.0, 5.0, 3.0));
        let images = room.image_sources(s, 1);
        let report = classify(s, r, &obstacles, None, &images);
        assert_eq!(report.reflections_total, 0);
        assert_eq!(report.condition, Condition::Obstruction);
        // Degenerate input never panics.
        let nan = v(f64::NAN, 0.0, 0.0);
        let report = classify(nan, r, &obstacles, Some(&room), &images);
        assert_eq!(report.direct_blocked_by, None);
    }

    #[test]
    fn source_inside_cabinet_is_diagnosable() {
        let (room, obstacles, _, r) = cabinet_room();
        let s = v(3.0, 2.5, 1.0);
        assert!(obstacles[0].contains(s));
        let images = room.image_sources(s, 1);
        let report = classify(s, r, &obstacles, Some(&room), &images);
        assert_eq!(report.first_order_reaching, 0);
        assert_eq!(report.condition, Condition::Occlusion);
    }

    /// Hostile input never panics: NaN, infinities, huge and tiny values,
    /// degenerate shapes, tampered images.
    #[test]
    fn never_panics() {
        let specials = [
            0.0,
            -0.0,
            1.0,
            -2.5,
            1e-300,
            1e300,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        struct Lcg(u64, [f64; 10]);
        impl Lcg {
            fn next(&mut self) -> f64 {
                self.0 = self
                    .0
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let r = self.0 >> 33;
                if r.is_multiple_of(4) {
                    self.1[(r as usize / 4) % self.1.len()]
                } else {
                    (r % 2000) as f64 / 100.0 - 5.0
                }
            }
            fn p(&mut self) -> DVec3 {
                v(self.next(), self.next(), self.next())
            }
        }
        let mut g = Lcg(0x9e37_79b9_7f4a_7c15, specials);
        for _ in 0..2000 {
            let (a, b, c, d) = (g.p(), g.p(), g.p(), g.p());
            let room = Room { min: a, max: b };
            let wall = Wall::new(c, d, g.p()).with_opening(Opening::new(
                g.next(),
                g.next(),
                g.next(),
                g.next(),
            ));
            let obstacles = [
                Obstacle::from(AlignedBox::new(g.p(), g.p())),
                Obstacle::from(wall),
            ];
            let (s, r) = (g.p(), g.p());
            for o in &obstacles {
                let _ = (o.validate(), o.contains(s), o.segment_blocked(s, r));
            }
            let _ = (room.validate(), room.contains(s));
            let mut images = room.image_sources(s, 3);
            images.push(ImageSource {
                position: g.p(),
                source: s,
                index: [i32::MAX, i32::MIN, 3],
                order: usize::MAX,
                walls: [7; MAX_ORDER],
            });
            for image in &images {
                let _ = (image.walls(), room.reflection_path(image, r));
            }
            let _ = classify(s, r, &obstacles, Some(&room), &images);
        }
        // Valid rooms with sources and receivers on walls and corners.
        let room = Room::from_size(v(4.0, 3.0, 2.5));
        for s in [room.min, room.max, v(0.0, 1.5, 1.0), v(4.0, 3.0, 1.0)] {
            let images = room.image_sources(s, MAX_ORDER);
            assert_eq!(
                images.len(),
                (1..=MAX_ORDER).map(|k| 4 * k * k + 2).sum::<usize>()
            );
            for r in [
                room.min,
                v(0.0, 1.5, 1.0),
                v(2.0, 3.0, 0.0),
                v(1.0, 1.0, 1.0),
            ] {
                for image in &images {
                    if let Some(path) = room.reflection_path(image, r) {
                        for (p, &w) in path.points().iter().zip(path.walls()) {
                            assert!(room.on_wall(w, *p));
                        }
                    }
                }
                let _ = classify(s, r, &[], Some(&room), &images);
            }
        }
    }
}
