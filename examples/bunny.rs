//! A 64 x 64 cloth falls onto the Stanford bunny and drapes over it (the paper's Table VI/VIII
//! scene). The bunny's collider is built automatically from its mesh.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example bunny`
//!
//! Drag to orbit, scroll to zoom; 1, 3 and 5 rebuild the collider at n = 1, 3, 5 and drop the
//! cloth again; B shows the spheres and boxes of the BVH; R resets; Space pauses.

mod common;

use bevy::prelude::*;

fn main() {
    common::example_app("bevy_bvh_cloth: bunny")
        .add_systems(Startup, common::model_drop_scene("models/bunny.obj", Vec2::new(-0.24, -0.09), 0.99))
        .run();
}
