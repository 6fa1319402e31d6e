//! A 64 x 64 cloth falls onto the Stanford dragon and drapes over it (the paper's Table VI/VIII
//! scene). The dragon's collider is built automatically from its mesh.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example dragon`
//!
//! Drag to orbit, scroll to zoom; 1, 3 and 5 rebuild the collider at n = 1, 3, 5 and drop the
//! cloth again; B shows the spheres and boxes of the BVH; R resets; Space pauses.

mod common;

use bevy::prelude::*;

fn main() {
    common::example_app("bevy_bvh_cloth: dragon")
        .add_systems(Startup, common::model_drop_scene("models/dragon.obj", Vec2::new(-0.23, -0.04), 0.71))
        .run();
}
