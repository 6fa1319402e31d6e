//! The plugin's integration tests, in one binary so that Bevy is linked once for all of them:
//! headless apps with `MinimalPlugins` on the CPU backend (`headless`), hostile OBJ files
//! through `bevy_obj` (`hostile_obj`), and the whole renderer on a real device with the GPU
//! backend (`render`).

mod headless;
mod hostile_obj;
mod render;
mod skinned_arm;
