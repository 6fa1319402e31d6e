//! Self-contact and contact between cloths: every particle is held a thickness away from every
//! triangle of its own cloth it is not a corner of, and every edge a thickness away from every
//! edge it shares no end with, within a cloth and against the other cloths stepped with it whose
//! collision layers its own meet ([`ContactBody::layers`]).
//!
//! Point against triangle, not point against point: with a thickness below the particle
//! spacing, a particle of one layer passes between the particles of another through the middle
//! of a triangle, so pairs of particles alone let two cloths cross each other. Held off the
//! triangles, a layer's particles meet the other layer's surface wherever they cross it. Edge
//! against edge as well: two layers can also cross where an edge of one passes through an edge
//! of the other with no particle near a triangle of the other layer (over a fold at 15 m/s
//! onto the bunny, tested without edges, 1,003 of the 1,326 times two of the cloth's triangles
//! came to intersect were that; the report's `self_contact_events` section).
//!
//! # Finding the pairs
//!
//! On the CPU, each cloth's triangles lie in a binary tree built once from its rest shape (the
//! triangles halved again and again at the median of their centroids along the longest side of
//! their box, so that each node is a compact piece of the cloth, down to leaves of at most
//! two), refitted each substep: each triangle's and each node's box over the substep (where its
//! corners were at the start and are now), grown by half the largest thickness, its extent
//! along the six diagonals of the axes (`x ± y`, `x ± z`, `y ± z`), grown likewise (by the
//! diagonals' length, `√2`, times as much), and a cone holding its triangles' normals at the
//! start and the end: at a leaf, about their mean direction, its angle the widest of theirs
//! from it; at an inner node, about the direction halfway between its children's axes, each
//! child's angle grown by its axis's angle from there (a cone wider than 45° is taken as every
//! direction: the walk skips nothing for it, and no join above it narrows it). The tree is
//! walked for the pairs of triangles whose boxes meet, each pair once, and a pair of triangles
//! stands for the contacts of their particles and edges: each particle and each edge is taken
//! by one of its triangles, a point tested against the other triangle of each pair its own is
//! in, and an edge against the edges of that triangle (a particle of no triangle takes part in
//! no contact). A path that came within the thickness of
//! a triangle, or went through it, at any speed, lies in boxes and extents that meet. Two nodes
//! whose boxes meet are passed over too when their extents along a diagonal lie apart: with its
//! box, a node is bounded by 18 planes (a k-DOP, Klosowski et al. 1998, "Efficient collision
//! detection using bounding volume hierarchies of k-DOPs"), which follow the parts of a
//! crumpled cloth that lie askew to the axes more closely than the box alone. Two triangles
//! that share no corner are dropped too when the line through their centroids separates them by
//! the thickness over the whole substep (their corners' spans along it now, each widened by the
//! farthest its corners moved): the boxes of a crumpled cloth's triangles lie askew to the
//! axes, and meet for most of the triangles one row apart on the cloth, which that line
//! separates.
//!
//! Most of a cloth is a gently curved sheet, whose triangles lie within the thickness of their
//! neighbours and never touch them: the walk skips each part of a cloth whose triangles are
//! joined through shared corners and whose normals at the substep's start and end all lie
//! within 45° of one direction ([`FLAT_COS`]), and each two such parts (or triangles) that
//! share a corner and are flat together: two cones of angles `a` and `b` whose axes lie `φ`
//! apart lie within the cone of angle `(a + b + φ) / 2` between them, within 45° when both
//! are and `cos φ >= sin(a + b)`. A connected surface whose normals lie within less
//! than 90° of one direction does not meet itself (Volino and Magnenat-Thalmann 1994,
//! "Efficient self-collision detection on smoothly discretized surface animations using
//! geometrical shape regularity"). Within 45° it is a height field no steeper than 45° over
//! the plane across that direction, so two of its particles lie at least 0.71 times as far
//! apart as along the sheet: only particles less than 1.41 times the thickness apart along it
//! can come within the thickness, and those are held apart by the cloth's springs, not by
//! contact, until the part bends further. (Within 60°, with the normals bounded by a box,
//! more is skipped and the cost falls further, but a fold of the core's `fast_folds_keep_off_themselves_with_block_descent`, onto
//! the bunny at 15 m/s, ended with 42 pairs of its triangles intersecting.)
//! Each node keeps its box in the rest shape and its particles that also belong to triangles
//! outside it, sorted, for the test of a shared corner. On the report's cloth of 128 x 128
//! draped on the bunny, the walk tests about 87,000 pairs of nodes a substep and hands about
//! 8,700 pairs of its 32,258 triangles to the tests below. With the normals bounded by a box
//! rather than a cone (the least cosine between the box's corners and its middle's direction),
//! 167,000 and 30,000: a box of unit normals reaches far off the sphere of directions, and of
//! the node pairs whose box was wider than 45°, seven in ten had every normal within 45° of
//! their mean. (With that box and the nodes' boxes alone, 230,000 and 34,000; without the line
//! between centroids as well, 80,000 pairs: three in five of those lay one row apart on the
//! cloth, and none of them made a contact. Counts of that scene in scratch builds.)
//!
//! The GPU backend finds its pairs in a hashed grid of the primitives (the triangles, then the
//! edges), rebuilt each substep (Teschner et al. 2003, "Optimized spatial hashing for
//! collision detection of deformable objects"): cells twice as wide as the largest thickness
//! plus the mean edge, every primitive entered in each cell its box over the substep, grown by
//! the thickness, overlaps, and a point (an edge) looking in the buckets of the cells its path
//! (its box over the substep) overlaps for the triangles (the later edges), taking each only
//! in the first cell that both cover. It skips no flat part: within one, it holds apart the
//! particles less than 1.41 times the thickness apart along the sheet that come within the
//! thickness, which the CPU leaves to the springs.
//!
//! Within a cloth a point and a triangle are skipped when the point is a corner of the
//! triangle, or lies within the thickness of the triangle's box in the rest shape, and two
//! edges when they share an end or their boxes in the rest shape lie within the thickness of
//! each other (neighbours on the cloth, not two layers): the cloth's own shape never fights
//! the contact.
//!
//! # Bounds
//!
//! The CPU's walk tests at most [`MAX_TESTS_PER_TRIANGLE`] pairs of nodes per triangle, and
//! stops there: everything at one point (a cloth collapsed by an absurd force) costs a bounded
//! amount per triangle, not the square of the count, and the node pairs left are counted in
//! [`ContactStats::clamped`], never silently. The GPU's grid examines at most
//! [`MAX_CANDIDATES`] primitives of a bucket, a point's path at most [`MAX_PATH_SPAN`] cells and
//! a triangle's or an edge's box at most [`MAX_SPAN`] cells along an axis.
//!
//! # Response
//!
//! A point `p` closer than the pair's thickness `h` (the mean of the two cloths') to a triangle,
//! at distance `d` from its closest point `q = Σ b_c x_c` (barycentric weights `b`), along the
//! unit direction `n` from `q` to `p`: the constraint `(x_p - q)·n >= h` is projected with the
//! particles' weights (1 free, 0 pinned), so `p` moves `w_p λ n` and each corner `-w_c b_c λ n`,
//! with `λ = (h - d) / (w_p + Σ w_c b_c²)`. Two edges closer than `h`, their closest points at
//! `s` and `t` along them, take the same projection with the ends' shares `1 - s`, `s`,
//! `-(1 - t)` and `-t` in place of `1` and `-b`. A particle a collider touched in the
//! substep's collision response ([`ContactBody::held`]) takes no part either, unless every
//! particle of the contact is held: where a model presses one layer into another, the layer on
//! the model cannot give way (the collider puts it back), so the other side takes the held
//! particles' share too (`λ` scaled by the ratio of the two denominators, at most
//! [`MAX_HELD_SCALE`]), and the layers do not cross.
//!
//! A point that changed sides of the triangle's plane during the substep (from the positions
//! at its start, [`ContactBody::prev`]) went through it if, where it crossed the plane, it was
//! within the thickness of the triangle as far along its own path (all four particles moving in
//! straight lines over the substep): `n` is then the face normal on the side it came from, and
//! `d` its depth below the plane, so it goes back the thickness above the side it left, however
//! far past the triangle it ended. Two edges that changed sides of each other along their
//! lines' common normal (the normal now turned to agree with the one at the start, so that a
//! turn is not taken for a crossing) went through each other if, where the lines met, the
//! edges were within the thickness: they go back to the sides they came from, the thickness
//! apart. If the particles of a contact approach, the normal part of their relative velocity is
//! taken off the same way, and the tangential part slowed by Coulomb friction.
//!
//! The points' contacts are found in parallel, pair by pair, and summed in the pairs' order (on
//! the CPU the walk's first steps make node pairs for the threads to share, each walked depth
//! first, their pairs joined in order); a particle in several contacts moves by the mean of its
//! corrections (Jacobi with averaging), so the result does not depend on the thread count. It
//! does depend on the pairs' order, through the rounding of the sums: the same pairs walked in
//! another order end up to millimetres apart where a particle lies at a contact's threshold
//! (the GPU's test against the CPU, `self_contact_agrees_with_the_cpu`). Then the edges'
//! contacts are found the same way from where those corrections left the particles, and
//! applied the same way: a point put back through a triangle takes its edges back with it, and
//! the edges' contacts then catch only what the points missed. Averaged together, the two
//! kinds of contact of one crossing would each pull a particle part of the way (a point
//! through a pinned sheet ended 1.3 mm above it for a thickness of 10 mm). A particle that
//! moved is checked against the colliders from where it was, so that contact never pushes
//! cloth through a collider.
//!
//! # Cloth that already crosses
//!
//! Contact keeps each particle on the side it came from, so two cloths that start crossed (or
//! that something forced through each other), or a cloth through itself (a pin dragged through
//! it), would be held as they are. Before the contacts of each substep, the triangles are
//! tested against each other at the substep's start (the pairs the search found, each once, by
//! an exact triangle–triangle test; a flat part does not meet itself): those of every two bodies, and those of one body that
//! share no corner and lie farther apart than its thickness in the rest shape (the pairs its
//! contacts test). A global intersection analysis after Baraff, Witkin and Kass 2003,
//! "Untangling Cloth", finds which particles lie through what:
//! - **Two bodies.** The triangles of one that meet the other cut it, and its other triangles
//!   fall into the parts the cuts leave, joined across shared edges. The largest part lies on
//!   the right side of the other body; the particles of the rest, and those of the cut
//!   triangles that are no corner of the largest part, lie through it, on the wrong side. Of
//!   the two bodies, the one with fewer particles on the wrong side is taken back.
//! - **One body through itself.** Its cut triangles, joined across shared edges, form rings,
//!   one on each side of a curve of intersection (a bump poked through another sheet of the
//!   cloth is ringed once on the bump and once on the sheet), and its other triangles fall
//!   into parts. What a ring encloses is the corners of its triangles and of the parts beside
//!   it other than the cloth's largest part, less that part's corners. Of two rings a pair of
//!   intersecting triangles joins, the one that encloses fewer particles is taken back through
//!   the other: the other's triangles and what it encloses are labelled a sheet of their own
//!   for the substep.
//!
//! Taken back, a particle's contacts with the other body or sheet, and theirs with it, take
//! the side opposite the one they are on as the side to go back to, so that the particles
//! within the thickness of it go through it to its far side. Their neighbours follow by the
//! springs, the cut moves outwards each substep, and what lies through shrinks until nothing
//! crosses. Two 32 x 32 cloths started crossed along a line end with 184, 0 and 0 pairs of
//! triangles intersecting at 0, 0.5 and 1 s (123 at 1 s without it; the core's
//! `two_cloths_started_crossed_come_apart`); a cloth folded on the ground with a bump of its
//! lower half poked through its upper half, with 103, 0 and 0 pairs of its own (84 at 1 s
//! without the analysis of one body; `a_cloth_poked_through_itself_comes_apart`); the same
//! cloth with a pin dragged up through its upper half and let go, 16 pairs at the release and
//! none 0.5 s later (12 without; `a_pin_dragged_through_the_cloth_leaves_no_tangle`). Where
//! nothing is enclosed (two cloths interlocked like two slotted cards, each passing through the
//! other's edge; a curve of intersection that runs out to the cloth's border on both sides of
//! it), nothing is taken back. While nothing crosses, the test is made once every sixteen
//! resolutions (a tick at Looper 16), so that cloth something forces through itself or another
//! is found within a tick. The GPU backend makes the same analysis in its own kernels
//! (`untangle.wgsl`: the crossing pairs from its hashed grid, the parts and rings by a parallel
//! union-find over the triangles' neighbours), with the same results on the two scenes above
//! (184, 0 and 0 pairs, and 103, 0 and 0, on lavapipe; the GPU tests
//! `two_cloths_started_crossed_come_apart_on_the_gpu` and
//! `a_cloth_poked_through_itself_comes_apart_on_the_gpu`). Where the CPU keeps sets, it keeps
//! one of each: a cloth crossed by several others is taken as crossing one of them, a part
//! beside several rings and a particle enclosed by several are taken by one, and a ring linked
//! to several goes back through one; a cloth that crosses itself and another at once has its
//! parts cut by both.
//!
//! # Limits
//!
//! On the CPU, a point is caught going through a triangle, and an edge through an edge, at any
//! speed; on the GPU, up to a path of [`MAX_PATH_SPAN`] cells a substep (an edge's box
//! [`MAX_SPAN`] cells). The crossings are found with the triangle's plane and the edges' lines
//! taken as they move linearly, not by the exact cubic of continuous collision detection, and
//! a part of a cloth is taken as flat from its normals at the substep's start and end, not in
//! between. The flat test does not look at the part's border: a sheet wound over itself like
//! a flattened cone, its normals all within 45° of one direction, is not caught. The edges'
//! contacts are looked for among the pairs found before the points' corrections (on the GPU,
//! in the buckets of before them): an edge those corrections moved near another that was not
//! near it is not met.

mod edge_edge;
mod point_triangle;
mod tree;
mod untangle;

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;
use glam::Vec3;
use rayon::prelude::*;

use crate::cloth::error::ClothError;
use crate::cloth::grid::SpringKind;
use crate::cloth::topology::ClothTopology;
use crate::colliders::collision::ColliderFrame;
use crate::colliders::layers::CollisionLayers;
use tree::SurfaceTree;

pub use tree::{FLAT_COS, MAX_TESTS_PER_TRIANGLE};
pub use untangle::UNTANGLE_EVERY;

/// Most triangles one particle examines in one grid cell's bucket for contact in a substep, on
/// the GPU backend's grid (see the [module docs](self)).
pub const MAX_CANDIDATES: usize = 256;

/// Most cells of the GPU backend's grid a triangle covers along an axis; a wider one (stretched
/// far beyond the others) is entered in the first `MAX_SPAN³` of its cells and counted as
/// clamped.
pub const MAX_SPAN: i32 = 4;

/// Most cells of the GPU backend's grid a particle's path over a substep is looked along, along
/// an axis: a path longer than a cell (twice the thickness and the mean edge: 48 mm, 46 m/s at
/// Looper 16 for the 64 x 64 cloth of 1 m at 8 mm) is looked along for its first two cells and
/// counted as clamped.
pub const MAX_PATH_SPAN: i32 = 2;

/// Most a contact's correction is scaled up when held particles take no part of it: the free
/// side takes the held side's share, up to this many times its own (a triangle whose only free
/// corner has a small weight at the contact would otherwise be levered far).
pub const MAX_HELD_SCALE: f32 = 16.0;

/// Above this many particles the contacts are found on the rayon pool.
const PARALLEL_MIN: usize = 2048;

/// How a cloth keeps off itself and other cloths.
///
/// `SelfContact::default()` fits any cloth: its thickness is taken from the cloth's own
/// particle spacing when the cloth is built ([`Self::AUTO_THICKNESS`]), and its friction is 0.3.
///
/// ```
/// # use bvh_cloth_core::{ClothParams, SelfContact};
/// let params = ClothParams { self_contact: Some(SelfContact::default()), ..Default::default() };
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub struct SelfContact {
    /// The least distance between a particle and a triangle it is not a corner of, in metres.
    /// At most the cloth's particle spacing (the mean rest length of its structural springs):
    /// thicker, and the cloth's own neighbouring triangles would push its particles. 0 (the
    /// default) is half that spacing, whatever the cloth's size and resolution.
    pub thickness: f32,
    /// Coulomb friction between layers (0 slides freely).
    pub friction: f32,
}

impl Default for SelfContact {
    fn default() -> Self {
        Self { thickness: 0.0, friction: 0.3 }
    }
}

impl SelfContact {
    /// The share of the cloth's particle spacing a thickness of 0 stands for: half, thick
    /// enough that a particle crossing a layer at up to half the spacing per substep is caught,
    /// and thin enough that the cloth's own triangles never push their neighbours.
    pub const AUTO_THICKNESS: f32 = 0.5;

    /// Checks the fields alone: a finite thickness, positive or 0 (see [`Self::thickness`]),
    /// and a non-negative, finite friction.
    pub fn validate(&self) -> Result<(), ClothError> {
        if self.thickness != 0.0 {
            ClothError::check_positive("self_contact.thickness", self.thickness)?;
        }
        ClothError::check_non_negative("self_contact.friction", self.friction)
    }

    /// The same contact with a thickness of 0 replaced by [`Self::AUTO_THICKNESS`] of
    /// `topology`'s particle spacing; any other thickness is kept.
    pub fn resolved_for(self, topology: &ClothTopology) -> Self {
        if self.thickness == 0.0 {
            Self { thickness: Self::AUTO_THICKNESS * particle_spacing(topology), ..self }
        } else {
            self
        }
    }

    /// [`Self::validate`], and a thickness no larger than `topology`'s particle spacing.
    pub fn validate_for(&self, topology: &ClothTopology) -> Result<(), ClothError> {
        self.validate()?;
        let spacing = particle_spacing(topology);
        if self.thickness > spacing {
            return Err(ClothError::ThicknessAboveSpacing { thickness: self.thickness, spacing });
        }
        Ok(())
    }
}

/// The mean rest length of `topology`'s structural springs: its particle spacing.
pub fn particle_spacing(topology: &ClothTopology) -> f32 {
    let (sum, count) = topology
        .spring_ends()
        .iter()
        .filter(|e| e.kind == SpringKind::Structural as u32)
        .fold((0.0f64, 0usize), |(sum, count), e| (sum + f64::from(e.rest), count + 1));
    if count == 0 { 0.0 } else { (sum / count as f64) as f32 }
}

/// One cloth's particles as contact sees them.
#[derive(Debug)]
pub struct ContactBody<'a> {
    /// The cloth's shape: its triangles, and its rest shape, which says which of its own
    /// triangles a point skips.
    pub topology: &'a ClothTopology,
    /// Its thickness and friction.
    pub contact: SelfContact,
    /// Its collision layers: the colliders its particles are checked against after contact,
    /// and the other bodies it keeps off (a body always keeps off itself).
    pub layers: CollisionLayers,
    /// 1 for a free particle, 0 for a pinned one.
    pub free: &'a [f32],
    /// 1 for a particle a collider touched in this substep's collision response, else 0 (or
    /// an empty slice for none): contact weighs it as pinned.
    pub held: &'a [f32],
    /// Positions at the start of the substep: a point that went through a triangle during it
    /// is put back on the side it came from.
    pub prev: &'a [Vec3],
    /// Positions, in the world.
    pub x: &'a mut [Vec3],
    /// Velocities.
    pub v: &'a mut [Vec3],
}

/// What one resolution found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContactStats {
    /// Point–triangle and edge–edge contacts, counted once by each free particle taking part
    /// (the point and the triangle's corners, or the two edges' ends). A pinned particle is
    /// never moved by contact.
    pub contacts: usize,
    /// The pairs of nodes of the triangles' tree left untested when the walk reached its
    /// bound ([`MAX_TESTS_PER_TRIANGLE`] per triangle): 0 when every pair was looked at.
    pub clamped: usize,
    /// Particles that lay on the wrong side of another cloth, or of another sheet of their own
    /// cloth, at the substep's start (cloth that already crossed), whose contacts with it took
    /// them back through.
    pub wrong_side: usize,
}

/// The triangles' tree and the scratch of contact resolution, kept between substeps.
#[derive(Clone, Debug, Default)]
pub struct ContactSolver {
    prev: Vec<Vec3>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    free: Vec<f32>,
    /// 1 for a particle a collider touched in the substep.
    held: Vec<f32>,
    /// The serial of each body's topology ([`ClothTopology::serial`]) that `owner`,
    /// `triangles`, `edges` and `tree` were made for.
    gathered_for: Vec<u64>,
    /// For each particle, its body and its index in it.
    owner: Vec<(u32, u32)>,
    /// Every body's triangles: its body and its corners' flat indices.
    triangles: Vec<(u32, [u32; 3])>,
    /// Every body's edges: its body and its ends' flat indices.
    edges: Vec<(u32, [u32; 2])>,
    /// The bodies' triangles in a tree, refitted each substep.
    tree: SurfaceTree,
    /// The pairs of triangles the tree found this substep.
    pairs: Vec<(u32, u32)>,
    /// For each particle, the label (in `sheet`) of the other body or sheet it lies on the
    /// wrong side of at the substep's start (`untangle::NO_BODY` for none): its contacts with
    /// that body or sheet take it back through.
    wrong_side: Vec<u32>,
    /// For each particle, the label of the body or sheet it belongs to: its body's index, or
    /// a label of its own for a sheet of a body that another sheet of it passes through.
    sheet: Vec<u32>,
    /// Whether any particle is on the wrong side this substep.
    tangled: bool,
    /// Resolutions left before the next test for crossing bodies (`untangle`).
    untangle_wait: u32,
    /// Each particle's summed corrections and the number of contacts it took part in, zero
    /// outside [`Self::apply`], and the particles they moved there.
    dx: Vec<Vec3>,
    dv: Vec<Vec3>,
    count: Vec<u32>,
    moved: Vec<u32>,
}

/// One contact of four particles (a point and a triangle's corners, or two edges' ends): the
/// constraint `Σ coef_k x_k · n >= h`, and the correction each particle takes part in, per unit
/// of its weight.
#[derive(Clone, Copy, Debug)]
struct Contact {
    /// The particles (flat indices): the point then the corners, or the first edge's ends then
    /// the second's.
    ids: [u32; 4],
    /// Each particle's share of the constraint: 1 for the point and minus its barycentric
    /// weights for the corners; `1 - s`, `s`, `t - 1` and `-t` for edges whose closest points
    /// lie at `s` and `t` along them.
    coef: [f32; 4],
    /// Unit normal, from the triangle to the point, or from the second edge to the first.
    n: Vec3,
    /// Position correction along `n` per unit weight.
    lambda: f32,
    /// Velocity correction per unit weight (normal and friction).
    impulse: Vec3,
    /// The weights the corrections are taken with.
    w: [f32; 4],
}

impl ContactSolver {
    /// Holds every particle of `bodies` its thickness off every triangle (within a body and
    /// across bodies), as the [module docs](self) say, then checks the particles that moved
    /// against `frames` from where they were. `bodies` are written in place.
    pub fn resolve(&mut self, bodies: &mut [ContactBody<'_>], frames: &[ColliderFrame<'_>]) -> ContactStats {
        self.gather(bodies);
        let n = self.x.len();
        let thickest = bodies.iter().map(|b| b.contact.thickness).fold(0.0f32, f32::max);
        if n < 2 || self.triangles.is_empty() || !(thickest.is_finite() && thickest > 0.0) {
            return ContactStats::default();
        }
        self.tree.refit(&self.prev, &self.x, 0.5 * thickest);
        let mut pairs = core::mem::take(&mut self.pairs);
        let meet = |a: usize, b: usize| bodies[a].layers.interacts_with(bodies[b].layers);
        let mut stats = ContactStats { clamped: self.tree.pairs(meet, &mut pairs), ..Default::default() };
        stats.wrong_side = self.find_wrong_sides(bodies, &pairs);
        // Points against triangles first, and their corrections made; then edges against
        // edges, from where those left the particles.
        let found = self.find(bodies, &pairs, |solver, pair, bodies, found| solver.point_contacts(pair, bodies, found));
        self.apply(bodies, frames, &found, &mut stats.contacts);
        self.tree.sweep_particles(&self.prev, &self.x);
        let found = self.find(bodies, &pairs, |solver, pair, bodies, found| solver.edge_contacts(pair, bodies, found));
        self.apply(bodies, frames, &found, &mut stats.contacts);
        self.pairs = pairs;
        stats
    }

    /// The contacts `each` finds for every pair of triangles in `pairs`, in their order
    /// whatever the threads, in runs.
    fn find(
        &self,
        bodies: &[ContactBody<'_>],
        pairs: &[(u32, u32)],
        each: impl Fn(&Self, (u32, u32), &[ContactBody<'_>], &mut Vec<Contact>) + Sync,
    ) -> Vec<Vec<Contact>> {
        let fold = |mut found: Vec<Contact>, &pair: &(u32, u32)| {
            each(self, pair, bodies, &mut found);
            found
        };
        if pairs.len() >= PARALLEL_MIN {
            pairs.par_iter().fold(Vec::new, fold).collect()
        } else {
            vec![pairs.iter().fold(Vec::new(), fold)]
        }
    }

    /// Moves every particle in `found`'s contacts by the mean of its corrections, checks it
    /// against the colliders from where it was, and writes it to its body and to the flat
    /// arrays; adds the particles' contacts to `contacts`.
    fn apply(
        &mut self,
        bodies: &mut [ContactBody<'_>],
        frames: &[ColliderFrame<'_>],
        found: &[Vec<Contact>],
        contacts: &mut usize,
    ) {
        // Zero between calls: each particle a contact moved is cleared after its move.
        let n = self.x.len();
        self.dx.resize(n, Vec3::ZERO);
        self.dv.resize(n, Vec3::ZERO);
        self.count.resize(n, 0);
        self.moved.clear();
        for found in found {
            for c in found {
                for ((&k, &coef), &w) in c.ids.iter().zip(&c.coef).zip(&c.w) {
                    let k = k as usize;
                    if w > 0.0 {
                        if self.count[k] == 0 {
                            self.moved.push(k as u32);
                        }
                        self.dx[k] += w * coef * c.lambda * c.n;
                        self.dv[k] += w * coef * c.impulse;
                        self.count[k] += 1;
                    }
                }
            }
        }
        let moved = core::mem::take(&mut self.moved);
        for &k in &moved {
            let k = k as usize;
            let count = core::mem::take(&mut self.count[k]);
            let (dx, dv) = (core::mem::take(&mut self.dx[k]), core::mem::take(&mut self.dv[k]));
            *contacts += count as usize;
            let mean = 1.0 / count as f32;
            let (mut p, mut vel) = (self.x[k] + dx * mean, self.v[k] + dv * mean);
            let (body, local) = self.owner[k];
            let body = &mut bodies[body as usize];
            for frame in frames.iter().filter(|f| body.layers.interacts_with(f.layers)) {
                frame.resolve(self.x[k], &mut p, &mut vel);
            }
            (body.x[local as usize], body.v[local as usize]) = (p, vel);
            (self.x[k], self.v[k]) = (p, vel);
        }
        self.moved = moved;
    }

    /// The contact of the particles `ids` whose constraint is `Σ coef_k x_k · n >= h`, short
    /// of it by `depth`, their relative velocity along the constraint `relative` and their
    /// friction `friction` (see the [module docs](self)): `None` when no particle of it is free.
    /// The held particles' share goes to the others, when there are others: the correction is
    /// scaled so that the free side alone makes the whole of it, at most [`MAX_HELD_SCALE`]
    /// times its own share.
    fn project(
        &self,
        ids: [u32; 4],
        coef: [f32; 4],
        n: Vec3,
        depth: f32,
        relative: Vec3,
        friction: f32,
    ) -> Option<Contact> {
        let weigh = |w: [f32; 4]| w.iter().zip(&coef).map(|(w, c)| w * c * c).sum::<f32>();
        let free = ids.map(|k| self.free[k as usize]);
        let denom = weigh(free);
        if denom <= 0.0 {
            return None;
        }
        let unheld = ids.map(|k| self.free[k as usize] * (1.0 - self.held[k as usize]));
        let unheld_denom = weigh(unheld);
        let (w, scale) =
            if unheld_denom > 0.0 { (unheld, (denom / unheld_denom).min(MAX_HELD_SCALE)) } else { (free, 1.0) };
        let vn = relative.dot(n);
        let impulse = if vn < 0.0 {
            let tangential = relative - vn * n;
            let speed = tangential.length();
            let slow = if speed > 0.0 { (friction * -vn / speed).min(1.0) } else { 0.0 };
            -(vn * n + slow * tangential) / denom * scale
        } else {
            Vec3::ZERO
        };
        Some(Contact { ids, coef, n, lambda: depth / denom * scale, impulse, w })
    }

    /// Copies every body's particles into the flat arrays, and, when the bodies' topologies
    /// changed, their triangles and edges, and builds their tree again.
    fn gather(&mut self, bodies: &[ContactBody<'_>]) {
        self.prev.clear();
        self.x.clear();
        self.v.clear();
        self.free.clear();
        self.held.clear();
        for body in bodies {
            let n = body.topology.len();
            assert!(
                body.x.len() >= n && body.v.len() >= n && body.free.len() >= n && body.prev.len() >= n,
                "a contact body holds fewer particles than its topology"
            );
            self.prev.extend_from_slice(&body.prev[..n]);
            self.x.extend_from_slice(&body.x[..n]);
            self.v.extend_from_slice(&body.v[..n]);
            self.free.extend_from_slice(&body.free[..n]);
            match body.held.get(..n) {
                Some(held) => self.held.extend_from_slice(held),
                None => self.held.extend((0..n).map(|i| body.held.get(i).copied().unwrap_or(0.0))),
            }
        }
        if self.gathered_for.iter().copied().eq(bodies.iter().map(|b| b.topology.serial())) {
            return;
        }
        self.gathered_for = bodies.iter().map(|b| b.topology.serial()).collect();
        self.owner.clear();
        self.triangles.clear();
        self.edges.clear();
        let mut first = 0;
        for (b, body) in bodies.iter().enumerate() {
            let n = body.topology.len() as u32;
            self.owner.extend((0..n).map(|i| (b as u32, i)));
            for t in body.topology.triangles() {
                self.triangles.push((b as u32, t.map(|k| first + k)));
            }
            first += n;
        }
        // The edges after every triangle, body by body.
        let mut first = 0;
        for (b, body) in bodies.iter().enumerate() {
            for &[p, q] in body.topology.edges() {
                self.edges.push((b as u32, [first + p, first + q]));
            }
            first += body.topology.len() as u32;
        }
        let topologies: Vec<&ClothTopology> = bodies.iter().map(|b| b.topology).collect();
        self.tree.build(&topologies);
    }
}

/// The substeps of a tick of cloths stepped together with self-contact: the most any of them
/// asks for alone (`own`), so that each keeps its own stability and contact is resolved after
/// every substep of each. Both backends take this rule; `None` for no cloth.
pub fn shared_substeps(own: impl IntoIterator<Item = u32>) -> Option<u32> {
    own.into_iter().max()
}
