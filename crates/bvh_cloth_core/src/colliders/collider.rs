//! A collider placed in the world by a pose: a mesh voxelised into spheres arranged in an LBVH
//! (paper section 2.4.1), or an exact [`Primitive`]. Moving a collider only changes its pose: no
//! rebuild. A skinned mesh's spheres also follow its joints (see [`crate::colliders::skinning`]).

use std::sync::Arc;

use glam::{Affine3A, UVec3, Vec3};

use crate::bvh::lbvh::Lbvh;
use crate::colliders::error::ColliderError;
use crate::colliders::exact_contact::TriangleSurface;
use crate::colliders::layers::CollisionLayers;
pub use crate::colliders::pose::ColliderPose;
use crate::colliders::primitives::Primitive;
use crate::colliders::skinning::{SkinRef, SkinScratch, SkinnedSpheres};
use crate::colliders::voxel_spheres::{Voxels, voxel_spheres_in};
use crate::mesh::MeshRef;

/// What a collider is made of, in its local frame.
#[derive(Clone, Debug)]
pub enum ColliderShape {
    /// A mesh voxelised into spheres. The tree is shared, so that a collider is cheap to clone
    /// with a new pose every frame.
    Spheres {
        /// The sphere tree.
        lbvh: Arc<Lbvh>,
        /// The voxels it was built with along each axis of the mesh's box.
        counts: UVec3,
        /// A skinned mesh's refit data: [`Collider::pose_skin`] moves the spheres with the
        /// joints. `None` for a rigid mesh.
        skin: Option<Arc<SkinnedSpheres>>,
        /// The mesh's own triangles, for exact contact (see [`crate::colliders::exact_contact`]): when
        /// present the cloth collides with them, held the margin off, and the spheres are only
        /// the collider's outline. `None`: the paper's sphere contact.
        surface: Option<Arc<TriangleSurface>>,
    },
    /// An exact convex shape.
    Primitive(Primitive),
}

/// A collider: a shape, where it is, and how its surface answers.
#[derive(Clone, Debug)]
pub struct Collider {
    /// The shape, in the collider's local frame.
    pub shape: ColliderShape,
    /// Extra thickness in world units added to the surface (the cloth's thickness).
    pub margin: f32,
    /// Coulomb friction coefficient of the surface (see [`crate::colliders::collision`]); 0, the paper's
    /// response, keeps the whole tangential velocity.
    pub friction: f32,
    /// Where the collider is.
    pub pose: ColliderPose,
    /// Which cloths collide with it: those whose [`ClothParams::layers`](crate::ClothParams::layers)
    /// and these meet ([`CollisionLayers::interacts_with`]). The default meets every cloth.
    pub layers: CollisionLayers,
}

impl Collider {
    /// Voxelises `mesh` at resolution `n` (an `n x n x n` grid over its AABB) and builds the
    /// LBVH over the spheres. The pose starts at identity, the margin and the friction at zero.
    pub fn from_mesh(mesh: MeshRef<'_>, n: u32) -> Result<Self, ColliderError> {
        Self::from_mesh_in(mesh, Voxels::PerAxis(n))
    }

    /// As [`Self::from_mesh`], with the voxels `voxels` gives (a count per axis or a size).
    pub fn from_mesh_in(mesh: MeshRef<'_>, voxels: Voxels) -> Result<Self, ColliderError> {
        let voxels = voxel_spheres_in(mesh, voxels)?;
        Ok(Self::from_tree(Lbvh::build(&voxels.spheres), voxels.counts))
    }

    /// A collider of a sphere tree built elsewhere (`counts`: the voxels it was built with).
    pub fn from_tree(lbvh: Lbvh, counts: UVec3) -> Self {
        Self::with_shape(ColliderShape::Spheres { lbvh: Arc::new(lbvh), counts, skin: None, surface: None })
    }

    /// A collider of a skinned mesh: voxelised in its bind pose as [`Self::from_mesh_in`] does,
    /// and moved with its joints by [`Self::pose_skin`]. Until the first pose it is the bind
    /// pose placed by [`Self::pose`].
    pub fn from_skinned_mesh(mesh: MeshRef<'_>, skin: SkinRef<'_>, voxels: Voxels) -> Result<Self, ColliderError> {
        let (lbvh, skinned) = SkinnedSpheres::build(mesh, skin, voxels)?;
        let counts = skinned.counts;
        let skin = Some(Arc::new(skinned));
        Ok(Self::with_shape(ColliderShape::Spheres { lbvh: Arc::new(lbvh), counts, skin, surface: None }))
    }

    /// Voxelises `mesh` at resolution `n`, as [`Self::from_mesh`], with exact contact against
    /// the same mesh's triangles ([`crate::colliders::exact_contact`]).
    pub fn from_mesh_exact(mesh: MeshRef<'_>, n: u32) -> Result<Self, ColliderError> {
        Self::from_mesh_in_exact(mesh, Voxels::PerAxis(n))
    }

    /// As [`Self::from_mesh_exact`], with the voxels `voxels` gives.
    pub fn from_mesh_in_exact(mesh: MeshRef<'_>, voxels: Voxels) -> Result<Self, ColliderError> {
        let mut collider = Self::from_mesh_in(mesh, voxels)?;
        if let ColliderShape::Spheres { surface, .. } = &mut collider.shape {
            *surface = Some(Arc::new(TriangleSurface::build(mesh)?));
        }
        Ok(collider)
    }

    /// The same collider with exact contact against `mesh`'s triangles, which must be the mesh
    /// its spheres were built from (see [`crate::colliders::exact_contact`]): a mesh whose triangles'
    /// box does not fit the spheres' box (it holds the triangles, and reaches at most a
    /// sphere's diameter past them) is refused with [`ColliderError::ExactMeshMismatch`].
    /// [`Self::from_mesh_exact`] takes the mesh once. A primitive is exact already and is
    /// returned as it is; a skinned collider keeps sphere contact, since its triangles move
    /// with the joints.
    pub fn with_exact_contact(mut self, mesh: MeshRef<'_>) -> Result<Self, ColliderError> {
        if let ColliderShape::Spheres { lbvh, surface, skin: None, .. } = &mut self.shape {
            let built = TriangleSurface::build(mesh)?;
            if !fits_spheres(lbvh, &built) {
                return Err(ColliderError::ExactMeshMismatch);
            }
            *surface = Some(Arc::new(built));
        }
        Ok(self)
    }

    /// How far the collision response keeps a particle off this collider, in metres: the
    /// margin, and with exact contact at least the surface's least thickness at its pose
    /// ([`TriangleSurface::least_thickness`]: a millionth of its box's diagonal, and enough
    /// steps of `f32` at its coordinates' magnitude that rounding cannot put a particle
    /// through it), which is what a zero margin gives.
    pub fn contact_thickness(&self) -> f32 {
        match self.surface() {
            Some(surface) => self.margin.max(surface.least_thickness(&self.pose) * self.pose.scale),
            None => self.margin,
        }
    }

    /// The triangles of a collider with exact contact.
    pub fn surface(&self) -> Option<&Arc<TriangleSurface>> {
        match &self.shape {
            ColliderShape::Spheres { surface, .. } => surface.as_ref(),
            ColliderShape::Primitive(_) => None,
        }
    }

    /// An exact primitive, checked by [`Primitive::validate`]. The pose starts at identity, the
    /// margin and the friction at zero.
    pub fn primitive(primitive: Primitive) -> Result<Self, ColliderError> {
        Ok(Self::with_shape(ColliderShape::Primitive(primitive.validate()?)))
    }

    fn with_shape(shape: ColliderShape) -> Self {
        Self { shape, margin: 0.0, friction: 0.0, pose: ColliderPose::default(), layers: CollisionLayers::DEFAULT }
    }

    /// The sphere tree of a mesh collider; `None` for a primitive.
    pub fn lbvh(&self) -> Option<&Arc<Lbvh>> {
        match &self.shape {
            ColliderShape::Spheres { lbvh, .. } => Some(lbvh),
            ColliderShape::Primitive(_) => None,
        }
    }

    /// A skinned mesh collider's refit data; `None` for a rigid mesh or a primitive.
    pub fn skin(&self) -> Option<&Arc<SkinnedSpheres>> {
        match &self.shape {
            ColliderShape::Spheres { skin, .. } => skin.as_ref(),
            ColliderShape::Primitive(_) => None,
        }
    }

    /// Moves a skinned collider's spheres to the pose `joint_matrices` gives (each joint's world
    /// transform times its inverse bind pose) and refits its tree; the spheres are then in
    /// world coordinates and the pose becomes the identity. A refused pose (too few or
    /// non-finite matrices) leaves the collider where it was. Does nothing to any other
    /// collider.
    pub fn pose_skin(&mut self, joint_matrices: &[Affine3A], scratch: &mut SkinScratch) -> Result<(), ColliderError> {
        let ColliderShape::Spheres { lbvh, skin: Some(skin), .. } = &mut self.shape else {
            return Ok(());
        };
        // The tree is shared with whoever cloned this collider (a renderer's copy): a refit
        // writes a copy of its own unless this is the only holder.
        skin.refit(joint_matrices, Arc::make_mut(lbvh), scratch)?;
        self.pose = ColliderPose::default();
        Ok(())
    }

    /// Checks a skinned collider's pose as [`Self::pose_skin`] does and places the collider in
    /// world coordinates (the identity pose), without refitting its spheres: for a renderer
    /// that refits them from the same matrices itself (`bvh_cloth_gpu`'s `SkinRefit`). Returns
    /// the clearance the refit gives the spheres at that pose, or `None` for a collider that is
    /// not skinned. A refused pose leaves the collider as it was.
    pub fn accept_skin_pose(&mut self, joint_matrices: &[Affine3A]) -> Result<Option<f32>, ColliderError> {
        let ColliderShape::Spheres { lbvh, skin: Some(skin), .. } = &self.shape else {
            return Ok(None);
        };
        let clearance = skin.check_pose(joint_matrices, lbvh)?;
        self.pose = ColliderPose::default();
        Ok(Some(clearance))
    }

    /// The primitive of a primitive collider; `None` for a mesh collider.
    pub fn as_primitive(&self) -> Option<&Primitive> {
        match &self.shape {
            ColliderShape::Primitive(primitive) => Some(primitive),
            ColliderShape::Spheres { .. } => None,
        }
    }

    /// Sets the extra thickness (world units).
    pub fn with_margin(mut self, margin: f32) -> Self {
        self.margin = margin;
        self
    }

    /// Sets the friction coefficient.
    pub fn with_friction(mut self, friction: f32) -> Self {
        self.friction = friction;
        self
    }

    /// Sets the collision layers.
    pub fn with_layers(mut self, layers: CollisionLayers) -> Self {
        self.layers = layers;
        self
    }

    /// Sets the pose.
    pub fn with_pose(mut self, pose: ColliderPose) -> Self {
        self.pose = pose;
        self
    }

    /// Number of leaf spheres (0 for a primitive).
    pub fn sphere_count(&self) -> usize {
        self.lbvh().map_or(0, |lbvh| lbvh.leaf_count())
    }
}

/// Whether `surface`'s triangles are those `lbvh`'s spheres were built around: the spheres'
/// box holds the triangles' box, and reaches at most the largest sphere's diameter past it
/// (both within a ten-thousandth of the triangles' diagonal).
fn fits_spheres(lbvh: &Lbvh, surface: &TriangleSurface) -> bool {
    let Some((lo, hi)) = lbvh.bounds() else { return false };
    let (t_lo, t_hi) =
        surface.triangles.iter().flatten().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let tolerance = 1.0e-4 * (t_hi - t_lo).length();
    let reach = 2.0 * lbvh.spheres.iter().map(|s| s.radius).fold(0.0, f32::max) + tolerance;
    let holds = (lo - tolerance).cmple(t_lo).all() && (hi + tolerance).cmpge(t_hi).all();
    let close = (t_lo - reach).cmple(lo).all() && (t_hi + reach).cmpge(hi).all();
    holds && close
}
