//! The shape of a cloth: its particles, their springs, their share of the mass and the surface
//! they form (paper section 2.1, for any triangle mesh).
//!
//! A [`ClothTopology`] comes from the generated grid ([`ClothTopology::grid`]) or from an
//! authored triangle mesh ([`ClothTopology::from_mesh`]):
//! - **Welding.** Mesh vertices at the same position (split at a UV or normal seam) become one
//!   particle; [`ClothTopology::vertex_particle`] says which particle each vertex shows, so the
//!   render vertices of a seam move together and no crack opens.
//! - **Springs.** Every edge is a structural spring. For every pair of triangles that shares an
//!   edge, the two corners opposite that edge are joined by a bending spring, which resists
//!   shear and bending. Rest lengths come from the mesh as authored, so a curved cape keeps its
//!   curve. On the grid the springs are the paper's stencil (4-neighbours, diagonals, two
//!   apart).
//! - **Stiffness that does not depend on the resolution.** Each spring carries a weight
//!   `A / L²`: the rest area `A` it spans (the triangles beside an edge, the two triangles a
//!   bending spring crosses) over its squared rest length `L`. Its stiffness is
//!   `spring_k * scale * A / L²`. In a sheet under strain `e`, a spring pulls with
//!   `k e L`, and a cut of unit length meets about `A / L²`-weighted springs per `L / A` of
//!   length, so the tension per metre is `spring_k e` whatever the spacing. On a square grid
//!   every weight is exactly 1.
//! - **Mass.** Each particle carries a third of the area of its triangles, as a share of the
//!   whole surface, but never less than [`MASS_FLOOR`] of the mean share: a scanned mesh's sliver
//!   triangles would otherwise leave particles with a ten-billionth of the cloth's mass on
//!   springs as stiff as any, which no explicit step can hold (the stability guard's substeps
//!   grow with the inverse square root of the lightest share) and which only slow a sweep's
//!   convergence. The grid gives every particle an equal share, as the paper does.
//! - **Per-particle lists (CSR).** Each particle lists its springs ([`SpringEnd`]) and its
//!   triangles, so that a kernel can gather everything a particle needs and write only that
//!   particle, with no atomics.

use std::collections::HashMap;

use glam::{DMat3, DVec3, Vec3};

use crate::cloth::colouring::ParticleColouring;
use crate::cloth::error::ClothError;
pub use crate::cloth::grid::SpringEnd;
use crate::cloth::grid::{ClothGrid, MAX_PARTICLES, STENCIL, SpringKind};
use crate::mesh::MeshRef;

/// The least mass share of a particle with mass on an authored mesh, as a fraction of the
/// mean share of the particles with mass (before the shares are scaled back to a sum of 1).
pub const MASS_FLOOR: f64 = 0.1;

/// `shares` (area shares summing to 1) with every nonzero share raised to [`MASS_FLOOR`] of the
/// mean nonzero share, scaled back to a sum of 1. A zero share (a particle no triangle with area
/// uses, which is held) stays zero.
fn floored_shares(shares: &[f64]) -> Vec<f32> {
    let massive = shares.iter().filter(|&&s| s > 0.0).count().max(1);
    let floor = MASS_FLOOR / massive as f64;
    let raised: Vec<f64> = shares.iter().map(|&s| if s > 0.0 { s.max(floor) } else { 0.0 }).collect();
    let total: f64 = raised.iter().sum();
    raised.iter().map(|&s| (s / total) as f32).collect()
}

/// A cloth's particles, springs and surface. Build it once per shape and share it (it is
/// immutable); see the [module docs](self).
#[derive(Clone, Debug, PartialEq)]
pub struct ClothTopology {
    rest: Vec<Vec3>,
    mass_share: Vec<f32>,
    inv_mass_share: Vec<f32>,
    spring_offsets: Vec<u32>,
    spring_ends: Vec<SpringEnd>,
    triangles: Vec<[u32; 3]>,
    edges: Vec<[u32; 2]>,
    triangle_offsets: Vec<u32>,
    triangle_list: Vec<u32>,
    triangle_slots: Vec<[u32; 3]>,
    vertex_particle: Vec<u32>,
    stencil: Option<ClothGrid>,
    stiffness_bound: [f32; 3],
    rest_area: f32,
    colouring: Result<ParticleColouring, ClothError>,
    serial: Serial,
}

/// A number that no other topology built in the process has, which says what a cache was made
/// for without comparing the shapes: a clone keeps it, holding the same shape (which never
/// changes). It takes no part in `==`, which compares the shapes.
#[derive(Clone, Copy, Debug)]
struct Serial(u64);

impl Serial {
    /// The next number.
    fn next() -> Self {
        static NEXT: core::sync::atomic::AtomicU64 = core::sync::atomic::AtomicU64::new(0);
        Self(NEXT.fetch_add(1, core::sync::atomic::Ordering::Relaxed))
    }
}

impl PartialEq for Serial {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl ClothTopology {
    /// The generated grid: the paper's stencil springs, equal masses, two triangles per cell.
    /// The CPU stepper runs it with its grid fast path.
    pub fn grid(grid: ClothGrid) -> Result<Self, ClothError> {
        let mut topology = Self::grid_as_mesh(grid)?;
        topology.stencil = Some(grid);
        Ok(topology)
    }

    /// The same particles, springs and masses as [`Self::grid`], stepped on the CPU through the
    /// general per-particle path that authored meshes take (for tests and benchmarks that
    /// compare the two).
    pub fn grid_as_mesh(grid: ClothGrid) -> Result<Self, ClothError> {
        grid.validate()?;
        let n = grid.len();
        let rest = grid.rest_positions(&glam::Affine3A::IDENTITY);
        let mut spring_offsets = Vec::with_capacity(n + 1);
        let mut spring_ends = Vec::with_capacity(n * STENCIL.len());
        spring_offsets.push(0);
        for r in 0..grid.rows as i32 {
            for c in 0..grid.cols as i32 {
                for s in STENCIL {
                    let (rr, cc) = (r + s.dr, c + s.dc);
                    if rr < 0 || cc < 0 || rr >= grid.rows as i32 || cc >= grid.cols as i32 {
                        continue;
                    }
                    spring_ends.push(SpringEnd {
                        other: grid.index(rr as usize, cc as usize) as u32,
                        kind: s.kind as u32,
                        rest: grid.rest_length(s.dr, s.dc),
                        weight: grid.weight(s.dr, s.dc),
                    });
                }
                spring_offsets.push(spring_ends.len() as u32);
            }
        }
        let triangles: Vec<[u32; 3]> = grid.triangle_indices().chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        Ok(Self::finish(
            rest,
            vec![1.0 / n as f32; n],
            spring_offsets,
            spring_ends,
            triangles,
            (0..n as u32).collect(),
            Some(ParticleColouring::grid(&grid)),
        ))
    }

    /// An authored triangle mesh (positions in the cloth's local frame, and an index list or
    /// none for "every three vertices a triangle"); see the [module docs](self).
    ///
    /// Non-manifold and disconnected meshes are legal cloth. Triangles that welding collapses
    /// (two corners at one point) are left out; zero-area triangles keep their edges but carry
    /// no mass. A vertex that no triangle uses becomes a particle with no mass, which stays
    /// where it was built.
    pub fn from_mesh(mesh: MeshRef<'_>) -> Result<Self, ClothError> {
        mesh.check()?;
        let positions = mesh.positions;
        let corners: Vec<u32> = match mesh.indices {
            Some(indices) => indices.to_vec(),
            None => (0..positions.len() as u32).collect(),
        };

        // Weld: one particle per distinct position (+0 and -0 are the same point).
        let key = |p: [f32; 3]| p.map(|x| if x == 0.0 { 0u32 } else { x.to_bits() });
        let mut welded: HashMap<[u32; 3], u32> = HashMap::with_capacity(positions.len());
        let mut rest = Vec::new();
        let vertex_particle: Vec<u32> = positions
            .iter()
            .map(|&p| {
                *welded.entry(key(p)).or_insert_with(|| {
                    rest.push(Vec3::from(p));
                    rest.len() as u32 - 1
                })
            })
            .collect();
        if rest.len() > MAX_PARTICLES as usize {
            return Err(ClothError::TooManyParticles { particles: rest.len(), max: MAX_PARTICLES });
        }

        // Triangles over particles; collapsed ones are dropped.
        let triangles: Vec<[u32; 3]> = corners
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]].map(|v| vertex_particle[v as usize]))
            .filter(|[a, b, c]| a != b && b != c && a != c)
            .collect();
        let at = |i: u32| rest[i as usize].as_dvec3();
        let areas: Vec<f64> =
            triangles.iter().map(|&[a, b, c]| 0.5 * (at(b) - at(a)).cross(at(c) - at(a)).length()).collect();
        let total_area: f64 = areas.iter().sum();
        if !(total_area > 0.0 && total_area.is_finite()) {
            return Err(ClothError::MeshWithoutArea);
        }
        let mut mass_share = vec![0.0f64; rest.len()];
        for (t, &area) in triangles.iter().zip(&areas) {
            for &p in t {
                mass_share[p as usize] += area / (3.0 * total_area);
            }
        }

        // Edges, grouped by their two particles: (low, high, triangle, opposite corner).
        let mut edges: Vec<(u32, u32, u32, u32)> = Vec::with_capacity(3 * triangles.len());
        for (k, &[a, b, c]) in triangles.iter().enumerate() {
            for (p, q, opposite) in [(a, b, c), (b, c, a), (c, a, b)] {
                edges.push((p.min(q), p.max(q), k as u32, opposite));
            }
        }
        edges.sort_unstable();
        let mut springs = SpringList::default();
        for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            let (a, b) = (group[0].0, group[0].1);
            let area: f64 = group.iter().map(|e| areas[e.2 as usize]).sum();
            springs.add(a, b, area, SpringKind::Structural, &rest);
        }
        for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            for (i, first) in group.iter().enumerate() {
                for second in &group[i + 1..] {
                    let area = areas[first.2 as usize] + areas[second.2 as usize];
                    springs.add(first.3, second.3, area, SpringKind::Bending, &rest);
                }
            }
        }
        let (spring_offsets, spring_ends) = springs.into_csr(&rest);
        Ok(Self::finish(
            rest,
            floored_shares(&mass_share),
            spring_offsets,
            spring_ends,
            triangles,
            vertex_particle,
            None,
        ))
    }

    /// The per-particle triangle lists, inverse mass shares and the stiffness bound, from the
    /// rest; the colouring given, or a greedy one.
    fn finish(
        rest: Vec<Vec3>,
        mass_share: Vec<f32>,
        spring_offsets: Vec<u32>,
        spring_ends: Vec<SpringEnd>,
        triangles: Vec<[u32; 3]>,
        vertex_particle: Vec<u32>,
        colouring: Option<ParticleColouring>,
    ) -> Self {
        let n = rest.len();
        let mut triangle_offsets = vec![0u32; n + 1];
        for t in &triangles {
            for &p in t {
                triangle_offsets[p as usize + 1] += 1;
            }
        }
        for i in 0..n {
            triangle_offsets[i + 1] += triangle_offsets[i];
        }
        let mut fill = triangle_offsets.clone();
        let mut triangle_list = vec![0u32; triangle_offsets[n] as usize];
        let mut triangle_slots = vec![[0u32; 3]; triangles.len()];
        for (k, (t, slots)) in triangles.iter().zip(&mut triangle_slots).enumerate() {
            for (&p, slot) in t.iter().zip(slots) {
                *slot = fill[p as usize];
                triangle_list[fill[p as usize] as usize] = k as u32;
                fill[p as usize] += 1;
            }
        }
        let mut edges: Vec<[u32; 2]> = triangles
            .iter()
            .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]].map(|[p, q]| [p.min(q), p.max(q)]))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let inv_mass_share: Vec<f32> = mass_share.iter().map(|&s| if s > 0.0 { 1.0 / s } else { 0.0 }).collect();
        let mut stiffness_bound = [0.0f32; 3];
        for i in 0..n {
            let mut per_kind = [DMat3::ZERO; 3];
            for end in &spring_ends[spring_offsets[i] as usize..spring_offsets[i + 1] as usize] {
                let d = (rest[end.other as usize] - rest[i]).as_dvec3().normalize_or_zero();
                per_kind[end.kind as usize] += f64::from(end.weight) * outer(d);
            }
            for (bound, s) in stiffness_bound.iter_mut().zip(per_kind) {
                *bound = bound.max((largest_eigenvalue(s) * f64::from(inv_mass_share[i])) as f32);
            }
        }
        let colouring = match colouring {
            Some(known) => Ok(known),
            None => ParticleColouring::greedy(n, &spring_offsets, &spring_ends),
        };
        let rest_area = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|p| rest[p as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum::<f64>() as f32;
        Self {
            rest,
            mass_share,
            inv_mass_share,
            spring_offsets,
            spring_ends,
            triangles,
            edges,
            triangle_offsets,
            triangle_list,
            triangle_slots,
            vertex_particle,
            stencil: None,
            stiffness_bound,
            rest_area,
            colouring,
            serial: Serial::next(),
        }
    }

    /// A number that no other topology built in the process has (a clone keeps it): two
    /// topologies with the same serial hold the same shape.
    pub(crate) fn serial(&self) -> u64 {
        self.serial.0
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// Whether there is no particle (never true for a built topology).
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Rest positions in the cloth's local frame.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    /// The area of the rest surface in square metres: its triangles' areas summed.
    pub fn rest_area(&self) -> f32 {
        self.rest_area
    }

    /// Each particle's share of the cloth's mass (they sum to 1; zero for a particle that no
    /// triangle with area uses).
    pub fn mass_share(&self) -> &[f32] {
        &self.mass_share
    }

    /// `1 / mass_share`, and 0 for a massless particle.
    pub fn inv_mass_share(&self) -> &[f32] {
        &self.inv_mass_share
    }

    /// Where each particle's springs start in [`Self::spring_ends`] (one more entry than there
    /// are particles).
    pub fn spring_offsets(&self) -> &[u32] {
        &self.spring_offsets
    }

    /// Every particle's springs, particle by particle: each spring appears once from each end.
    pub fn spring_ends(&self) -> &[SpringEnd] {
        &self.spring_ends
    }

    /// The springs of particle `i`.
    pub fn springs_of(&self, i: usize) -> &[SpringEnd] {
        &self.spring_ends[self.spring_offsets[i] as usize..self.spring_offsets[i + 1] as usize]
    }

    /// Number of springs (each counted once).
    pub fn spring_count(&self) -> usize {
        self.spring_ends.len() / 2
    }

    /// The surface's triangles over particles, counter-clockwise as authored.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The surface's edges, each once (the sides of its triangles, lower particle first), in
    /// order.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// Where each particle's triangles start in [`Self::triangle_list`] (one more entry than
    /// there are particles).
    pub fn triangle_offsets(&self) -> &[u32] {
        &self.triangle_offsets
    }

    /// Every particle's triangles (indices into [`Self::triangles`]), particle by particle.
    pub fn triangle_list(&self) -> &[u32] {
        &self.triangle_list
    }

    /// Where each triangle stands in [`Self::triangle_list`] under each of its corners:
    /// `triangle_list[triangle_slots()[t][c]] == t` for every corner `c` of triangle `t`. A
    /// value per triangle written at these places lies in each particle's own run of the list,
    /// in the list's order.
    pub fn triangle_slots(&self) -> &[[u32; 3]] {
        &self.triangle_slots
    }

    /// The triangles of particle `i`.
    pub fn triangles_of(&self, i: usize) -> &[u32] {
        &self.triangle_list[self.triangle_offsets[i] as usize..self.triangle_offsets[i + 1] as usize]
    }

    /// The particle each mesh vertex shows (the identity on the grid).
    pub fn vertex_particle(&self) -> &[u32] {
        &self.vertex_particle
    }

    /// The grid, when this is the generated grid and the CPU may use its fast path.
    pub fn stencil(&self) -> Option<&ClothGrid> {
        self.stencil.as_ref()
    }

    /// Per spring kind, `max_i λ_i / mass_share_i`, where `λ_i` is the largest eigenvalue of
    /// `Σ weight d dᵀ` over particle `i`'s springs of that kind (unit rest directions `d`); see
    /// [`crate::ClothParams::max_stable_substep`].
    pub fn stiffness_bound(&self) -> [f32; 3] {
        self.stiffness_bound
    }

    /// The particles grouped so that no spring joins two of one colour (see
    /// `cloth::colouring`), or why the mesh has none within the limit.
    pub fn colouring(&self) -> Result<&ParticleColouring, ClothError> {
        self.colouring.as_ref().map_err(Clone::clone)
    }
}

/// Springs gathered from a mesh, each particle pair once: a bending spring between two
/// particles an edge already joins is left out, and bending springs that meet twice (a
/// non-manifold edge) add their areas.
#[derive(Default)]
struct SpringList {
    springs: Vec<(u32, u32, f64, SpringKind)>,
    by_pair: HashMap<(u32, u32), usize>,
}

impl SpringList {
    fn add(&mut self, a: u32, b: u32, area: f64, kind: SpringKind, rest: &[Vec3]) {
        if a == b {
            return;
        }
        let pair = (a.min(b), a.max(b));
        match self.by_pair.get(&pair) {
            Some(&k) if self.springs[k].3 == SpringKind::Bending && kind == SpringKind::Bending => {
                self.springs[k].2 += area;
            }
            Some(_) => {}
            None => {
                let length = rest[a as usize].distance(rest[b as usize]);
                if length > 0.0 {
                    self.by_pair.insert(pair, self.springs.len());
                    self.springs.push((pair.0, pair.1, area, kind));
                }
            }
        }
    }

    /// Each particle's springs, in the order the springs were added.
    fn into_csr(self, rest: &[Vec3]) -> (Vec<u32>, Vec<SpringEnd>) {
        let particles = rest.len();
        let mut offsets = vec![0u32; particles + 1];
        for &(a, b, ..) in &self.springs {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for i in 0..particles {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut ends = vec![SpringEnd::default(); offsets[particles] as usize];
        for (a, b, area, kind) in self.springs {
            let length = rest[a as usize].as_dvec3().distance(rest[b as usize].as_dvec3());
            let (rest, weight) = (length as f32, (area / (length * length)) as f32);
            for (from, to) in [(a, b), (b, a)] {
                ends[fill[from as usize] as usize] = SpringEnd { other: to, kind: kind as u32, rest, weight };
                fill[from as usize] += 1;
            }
        }
        (offsets, ends)
    }
}

fn outer(d: DVec3) -> DMat3 {
    DMat3::from_cols(d * d.x, d * d.y, d * d.z)
}

/// The largest eigenvalue of a symmetric 3 x 3 matrix (the trigonometric closed form).
fn largest_eigenvalue(m: DMat3) -> f64 {
    let [a, b, c] = m.to_cols_array_2d();
    let off = a[1] * a[1] + a[2] * a[2] + b[2] * b[2];
    if off == 0.0 {
        return a[0].max(b[1]).max(c[2]);
    }
    let q = (a[0] + b[1] + c[2]) / 3.0;
    let p2 = (a[0] - q).powi(2) + (b[1] - q).powi(2) + (c[2] - q).powi(2) + 2.0 * off;
    let p = (p2 / 6.0).sqrt();
    let shifted = (m - DMat3::from_diagonal(DVec3::splat(q))) * (1.0 / p);
    let r = (shifted.determinant() / 2.0).clamp(-1.0, 1.0);
    q + 2.0 * p * (r.acos() / 3.0).cos()
}

#[cfg(test)]
mod tests {
    use glam::{UVec2, Vec2};

    use super::*;

    /// A unit square of two triangles, with its four corners duplicated per triangle (as a
    /// mesh split at a UV seam along the diagonal is).
    fn split_square() -> (Vec<[f32; 3]>, Vec<u32>) {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0]];
        (vec![p[0], p[2], p[1], p[1], p[2], p[3]], vec![0, 1, 2, 3, 4, 5])
    }

    #[test]
    fn seams_weld_and_every_vertex_shows_its_particle() {
        let (positions, indices) = split_square();
        let t = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        assert_eq!(t.len(), 4, "six vertices at four points are four particles");
        assert_eq!(t.vertex_particle(), &[0, 1, 2, 2, 1, 3]);
        for (v, &p) in t.vertex_particle().iter().enumerate() {
            assert_eq!(t.rest_positions()[p as usize], Vec3::from(positions[v]));
        }
        // Five edges (four sides and the diagonal) and one bending spring across the diagonal.
        assert_eq!(t.spring_count(), 6);
        let bending: Vec<_> = t.spring_ends().iter().filter(|e| e.kind == SpringKind::Bending as u32).collect();
        assert_eq!(bending.len(), 2, "one spring, seen from both ends");
        assert!((bending[0].rest - core::f32::consts::SQRT_2).abs() < 1e-6);
        // It spans both triangles (area 1) over its squared length 2.
        assert!((bending[0].weight - 0.5).abs() < 1e-6);
        // Sides border one triangle (area 1/2, length 1); the diagonal both (area 1, length √2).
        let side = t.springs_of(0).iter().find(|e| e.other == 2).unwrap();
        assert!((side.weight - 0.5).abs() < 1e-6);
        let diagonal = t.springs_of(1).iter().find(|e| e.other == 2).unwrap();
        assert!((diagonal.weight - 0.5).abs() < 1e-6);
        // Mass by area: the diagonal's corners carry two triangles, the others one.
        let share = t.mass_share();
        assert!((share[1] - 1.0 / 3.0).abs() < 1e-6 && (share[2] - 1.0 / 3.0).abs() < 1e-6);
        assert!((share[0] - 1.0 / 6.0).abs() < 1e-6 && (share[3] - 1.0 / 6.0).abs() < 1e-6);
    }

    #[test]
    fn the_grid_has_the_paper_stencil_and_equal_masses() {
        let grid = ClothGrid::new(Vec2::new(3.0, 2.0), UVec2::new(4, 3));
        let t = ClothTopology::grid(grid).unwrap();
        assert_eq!(t.len(), 12);
        assert!(t.stencil().is_some() && ClothTopology::grid_as_mesh(grid).unwrap().stencil().is_none());
        for i in 0..t.len() {
            let (r, c) = ((i / 4) as i32, (i % 4) as i32);
            let expected: Vec<u32> = STENCIL
                .iter()
                .filter(|s| (0..3).contains(&(r + s.dr)) && (0..4).contains(&(c + s.dc)))
                .map(|s| ((r + s.dr) * 4 + c + s.dc) as u32)
                .collect();
            let got: Vec<u32> = t.springs_of(i).iter().map(|e| e.other).collect();
            assert_eq!(got, expected, "particle {i}");
            for e in t.springs_of(i) {
                let d = t.rest_positions()[e.other as usize].distance(t.rest_positions()[i]);
                assert!((d - e.rest).abs() < 1e-6);
                assert!((e.weight - 1.0).abs() < 1e-6, "square cells weigh 1");
            }
        }
        assert!(t.mass_share().iter().all(|&s| s == 1.0 / 12.0));
        // Only the middle particle of a 5 x 5 grid has springs of every kind on every side:
        // λ = 2 per kind (two unit springs along each axis), over a share of 1/25.
        let t = ClothTopology::grid(ClothGrid::new(Vec2::splat(4.0), UVec2::splat(5))).unwrap();
        for bound in t.stiffness_bound() {
            assert!((bound - 50.0).abs() < 1e-4, "{bound}");
        }
    }

    #[test]
    fn a_curved_mesh_keeps_its_authored_rest_shape() {
        // A strip bent 90 degrees along its middle edge.
        let positions =
            [[0.0, 1.0, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0]];
        let indices = [0, 1, 2, 2, 1, 3, 2, 3, 4, 4, 3, 5];
        let t = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        // The bending spring across the fold (edge 2-3) joins corners 1 and 4 at their 3D
        // distance, not the flattened one.
        let across = t.springs_of(1).iter().find(|e| e.other == 4).expect("a spring across the fold");
        assert!((across.rest - 3.0f32.sqrt()).abs() < 1e-6, "{}", across.rest);
        assert_eq!(across.kind, SpringKind::Bending as u32);
    }

    /// A sliver triangle's corner off an edge carries a billionth of the sheet's area; it gets
    /// [`MASS_FLOOR`] of the mean share instead, the others keep their proportions, and the
    /// shares still sum to 1.
    #[test]
    fn a_sliver_triangle_gets_the_mass_floor() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.5, 0.0, -1.0e-9]];
        let indices = [0, 2, 1, 1, 2, 3, 0, 1, 4];
        let t = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        let share = t.mass_share();
        let mean = 1.0 / 5.0;
        let floor = MASS_FLOOR as f32 * mean;
        assert!((share.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert!(share[4] >= floor / (1.0 + MASS_FLOOR as f32) && share[4] <= floor, "{}", share[4]);
        // The square's corners keep their area shares' proportions: 0 and 3 touch one triangle,
        // 1 and 2 two.
        assert!((share[1] / share[0] - 2.0).abs() < 1e-5 && (share[0] - share[3]).abs() < 1e-7, "{share:?}");
        assert!(t.stiffness_bound().iter().all(|&b| b.is_finite() && b < 1.0e4), "{:?}", t.stiffness_bound());
    }

    #[test]
    fn non_manifold_disconnected_and_degenerate_meshes_are_cloth() {
        // Three triangles on one edge (0-1), a separate triangle, a triangle collapsed by
        // welding, a zero-area (collinear) one and a vertex no triangle uses.
        let positions = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
            [5.0, 0.0, 0.0],
            [6.0, 0.0, 0.0],
            [5.0, 0.0, 1.0],
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [9.0, 9.0, 9.0],
        ];
        let indices = [0, 1, 2, 1, 0, 3, 0, 1, 4, 5, 6, 7, 0, 8, 1, 0, 1, 9];
        let t = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        assert_eq!(t.len(), 10, "vertex 8 welds onto vertex 0");
        assert_eq!(t.triangles().len(), 5, "the collapsed triangle is left out");
        // Opposite corners 2, 3 and 4 of edge 0-1 are pairwise joined by bending springs.
        for (a, b) in [(2, 3), (2, 4), (3, 4)] {
            assert!(t.springs_of(a).iter().any(|e| e.other == b && e.kind == SpringKind::Bending as u32));
        }
        let share = t.mass_share();
        assert_eq!(share[t.vertex_particle()[10] as usize], 0.0, "an unused vertex carries no mass");
        assert_eq!(share[t.vertex_particle()[9] as usize], 0.0, "a zero-area triangle carries no mass");
        assert!((share.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert!(t.spring_ends().iter().all(|e| e.rest > 0.0 && e.weight.is_finite()));
        // Each triangle stands once under each corner, inside that corner's run of the list.
        for (k, (tri, slots)) in t.triangles().iter().zip(t.triangle_slots()).enumerate() {
            for (&p, &slot) in tri.iter().zip(slots) {
                let run = t.triangle_offsets()[p as usize]..t.triangle_offsets()[p as usize + 1];
                assert!(run.contains(&slot) && t.triangle_list()[slot as usize] == k as u32);
            }
        }
        let mut slots: Vec<u32> = t.triangle_slots().iter().flatten().copied().collect();
        slots.sort_unstable();
        assert_eq!(slots, (0..t.triangle_list().len() as u32).collect::<Vec<_>>());
    }

    #[test]
    fn meshes_that_cannot_be_cloth_say_why() {
        let mesh = |positions: &[[f32; 3]], indices: Option<&[u32]>| {
            ClothTopology::from_mesh(MeshRef { positions, indices }).unwrap_err()
        };
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(mesh(&[], None), ClothError::MeshWithoutVertices);
        assert_eq!(mesh(&tri, Some(&[0, 1])), ClothError::MeshIndicesNotTriangles { len: 2 });
        assert_eq!(mesh(&tri[..2], None), ClothError::MeshVerticesNotTriangles { vertices: 2 });
        assert_eq!(
            mesh(&tri, Some(&[0, 1, 3])),
            ClothError::MeshIndexOutOfRange { position: 2, index: 3, vertices: 3 }
        );
        let nan = [[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(mesh(&nan, None), ClothError::MeshVertexNotFinite { vertex: 1 });
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert_eq!(mesh(&line, None), ClothError::MeshWithoutArea);
        assert_eq!(mesh(&[[0.0; 3]; 3], None), ClothError::MeshWithoutArea);
    }

    #[test]
    fn refinement_keeps_the_material() {
        // The same 1 m square as a 3 x 3 and a 9 x 9 triangulated mesh: the stretch stiffness
        // of the sheet, (sum over structural springs of weight * (L·x)² / L²) / area, measured
        // along x is the same.
        let stretch = |n: u32| {
            let grid = ClothGrid::new(Vec2::ONE, UVec2::splat(n));
            let positions: Vec<[f32; 3]> =
                grid.rest_positions(&glam::Affine3A::IDENTITY).iter().map(|p| p.to_array()).collect();
            let t =
                ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&grid.triangle_indices()) })
                    .unwrap();
            let mut sum = 0.0f64;
            for i in 0..t.len() {
                for e in t.springs_of(i).iter().filter(|e| e.kind == SpringKind::Structural as u32) {
                    let d = t.rest_positions()[e.other as usize] - t.rest_positions()[i];
                    sum += 0.5 * f64::from(e.weight) * f64::from(d.x * d.x);
                }
            }
            sum
        };
        let (coarse, fine) = (stretch(3), stretch(9));
        assert!((coarse - fine).abs() < 1e-4 * coarse, "{coarse} vs {fine}");
    }

    #[test]
    fn largest_eigenvalue_matches_known_matrices() {
        let m = DMat3::from_cols_array(&[2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 1.0]);
        assert!((largest_eigenvalue(m) - 3.0).abs() < 1e-12);
        assert_eq!(largest_eigenvalue(DMat3::from_diagonal(DVec3::new(2.0, 0.0, 2.0))), 2.0);
    }
}
