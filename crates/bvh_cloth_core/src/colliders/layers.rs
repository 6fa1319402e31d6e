//! Collision layers: which colliders a cloth collides with, and which cloths keep off each
//! other, by 32 bit masks on both sides.
//!
//! Each side is a member of some layers (`memberships`) and collides with the members of
//! others (`filters`); two meet only when each one's filters hold a layer the other is a member
//! of. That is the rule of avian's `CollisionLayers` and of Rapier's interaction groups, so a
//! game's layer masks mean the same to its cloth as to its physics.

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;

/// The layers an object is a member of and the layers it collides with, as bit masks (layer
/// `k` is bit `k`). The default is a member of layer 0 that collides with every layer, so that
/// everything meets everything until a mask says otherwise.
///
/// ```
/// use bvh_cloth_core::CollisionLayers;
///
/// const PLAYER: u32 = 1 << 1;
/// const SCENERY: u32 = 1 << 2;
/// // A cape that collides with the scenery but not with its own wearer's collider.
/// let cape = CollisionLayers::new(CollisionLayers::DEFAULT.memberships, SCENERY);
/// let wearer = CollisionLayers::new(PLAYER, CollisionLayers::ALL);
/// let wall = CollisionLayers::new(SCENERY, CollisionLayers::ALL);
/// assert!(!cape.interacts_with(wearer));
/// assert!(cape.interacts_with(wall));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq, Hash))]
pub struct CollisionLayers {
    /// The layers this object is a member of.
    pub memberships: u32,
    /// The layers whose members this object collides with.
    pub filters: u32,
}

impl CollisionLayers {
    /// Every layer.
    pub const ALL: u32 = u32::MAX;
    /// A member of layer 0 that collides with every layer.
    pub const DEFAULT: Self = Self { memberships: 1, filters: Self::ALL };
    /// A member of no layer that collides with none: it meets nothing.
    pub const NONE: Self = Self { memberships: 0, filters: 0 };

    /// Layers with these masks.
    pub const fn new(memberships: u32, filters: u32) -> Self {
        Self { memberships, filters }
    }

    /// Whether the two meet: each one's filters hold a layer the other is a member of.
    pub const fn interacts_with(self, other: Self) -> bool {
        self.memberships & other.filters != 0 && other.memberships & self.filters != 0
    }
}

impl Default for CollisionLayers {
    fn default() -> Self {
        Self::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_sides_must_accept_each_other() {
        let a = CollisionLayers::new(0b01, 0b10);
        let b = CollisionLayers::new(0b10, 0b01);
        assert!(a.interacts_with(b) && b.interacts_with(a));
        // b is a member of what a filters for, but b's filters leave a's layer out.
        let c = CollisionLayers::new(0b10, 0b10);
        assert!(!a.interacts_with(c) && !c.interacts_with(a));
        assert!(CollisionLayers::DEFAULT.interacts_with(CollisionLayers::DEFAULT));
        assert!(!CollisionLayers::NONE.interacts_with(CollisionLayers::DEFAULT));
    }
}
