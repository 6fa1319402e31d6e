//! Which backend the plugin runs: the decision from what was asked and what the device offers.
//! (A device without compute shaders cannot be staged with lavapipe: limiting its features
//! breaks Bevy's own GPU preprocessing too, so the decision is tested on its own here.)

use bevy_bvh_cloth::prelude::*;

#[test]
fn falls_back_to_the_cpu_without_compute_shaders() {
    let no_compute = || Some(Err("the device does not run compute shaders".to_string()));
    assert_eq!(ActiveClothBackend::choose(ClothBackend::Auto, Some(Ok(()))), ActiveClothBackend::Gpu);
    assert_eq!(ActiveClothBackend::choose(ClothBackend::Auto, no_compute()), ActiveClothBackend::Cpu);
    assert_eq!(ActiveClothBackend::choose(ClothBackend::Auto, None), ActiveClothBackend::Cpu);
    assert_eq!(ActiveClothBackend::choose(ClothBackend::Gpu, Some(Ok(()))), ActiveClothBackend::Gpu);
    assert_eq!(ActiveClothBackend::choose(ClothBackend::Gpu, no_compute()), ActiveClothBackend::Cpu);
    assert_eq!(ActiveClothBackend::choose(ClothBackend::Gpu, None), ActiveClothBackend::Cpu);
    assert_eq!(ActiveClothBackend::choose(ClothBackend::Cpu, Some(Ok(()))), ActiveClothBackend::Cpu);
}
