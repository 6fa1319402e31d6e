//! Headless app tests of the plugin: MinimalPlugins, no window, no GPU, time advanced by hand.
//! They assert on the ECS state after whole seconds of simulation; the clock and the backend
//! decision are also tested on their own, without an app.

mod harness;

mod anchors;
mod authored;
mod backend;
mod clock;
mod colliders;
mod divergence;
pub(crate) mod gltf_character;
mod hanging;
mod hierarchy;
mod lifecycle;
mod parameters;
mod primitives;
mod schedule;
mod self_contact;
mod skinned;
mod skinned_cloth;
mod wind;
