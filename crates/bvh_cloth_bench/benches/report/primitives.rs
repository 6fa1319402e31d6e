//! The section `primitives`: exact primitives against voxelised meshes, the collision cost
//! per particle.

use super::*;

/// Exact primitives against voxelised meshes: the collision response's cost per particle for a
/// 64 x 64 cloth draped for 2 s on each collider (RK4, Looper 16), each particle pressed into
/// the surface by one substep of gravity, on one thread; and on a hardware GPU the
/// `node_update_final` kernel (integration and collision) of one tick.
pub(crate) fn primitives(bunny: &ObjMesh, gpu: Option<&Gpu>) {
    println!("\n## Primitives against mesh colliders: collision cost per particle, 64 x 64 cloth draped for 2 s\n");
    let shaped = |primitive: Primitive, translation: Vec3, rotation: Quat| {
        Collider::primitive(primitive)
            .expect("valid sizes")
            .with_margin(0.01)
            .with_friction(1.0)
            .with_pose(ColliderPose { translation, rotation, scale: 1.0 })
    };
    let lying = Quat::from_rotation_z(core::f32::consts::FRAC_PI_2);
    let colliders = [
        ("bunny mesh, n = 5".to_string(), collider(bunny, 5)),
        ("bunny mesh, n = 16".to_string(), collider(bunny, 16)),
        (
            "sphere r 0.4".to_string(),
            shaped(Primitive::Sphere { radius: 0.4 }, Vec3::new(0.0, 0.4, 0.0), Quat::IDENTITY),
        ),
        (
            "capsule r 0.2, 0.6 long, lying".to_string(),
            shaped(Primitive::Capsule { radius: 0.2, half_length: 0.3 }, Vec3::new(0.0, 0.2, 0.0), lying),
        ),
        (
            "box 0.8 x 0.4 x 0.6".to_string(),
            shaped(
                Primitive::Cuboid { half_extents: Vec3::new(0.4, 0.2, 0.3) },
                Vec3::new(0.0, 0.2, 0.0),
                Quat::IDENTITY,
            ),
        ),
        ("ground".to_string(), shaped(Primitive::HalfSpace { normal: Vec3::Y }, Vec3::ZERO, Quat::IDENTITY)),
    ];
    let hardware = gpu.filter(|gpu| !gpu.is_software());
    println!(
        "| collider | particles in contact | CPU ns / particle | mesh n = 5 / this | GPU node_update_final ms / tick |"
    );
    println!("|---|---|---|---|---|");
    let mut reference_ns = None;
    for (name, c) in &colliders {
        let cloth = drape(c, 2.0);
        let frame = ColliderFrame::new(c).expect("a usable collider");
        let h = TICK / 16.0;
        let paths: Vec<(Vec3, Vec3, Vec3)> = cloth
            .positions()
            .into_iter()
            .zip(cloth.velocities())
            .map(|(p, v)| (p, p + h * v + Vec3::new(0.0, -9.81 * h * h, 0.0), v))
            .collect();
        let mut contacts = 0;
        let seconds = best_of(9, || {
            contacts = 0;
            for &(prev, p, v) in &paths {
                let (mut p, mut v) = (p, v);
                contacts += usize::from(frame.resolve(prev, &mut p, &mut v));
                std::hint::black_box((p, v));
            }
        });
        let ns = seconds * 1e9 / paths.len() as f64;
        let reference = *reference_ns.get_or_insert(ns);
        let gpu_ms = hardware
            .and_then(|gpu| kernel_ms(gpu, c, std::slice::from_ref(&cloth)))
            .map_or("-".to_string(), |(ms, _)| format!("{:.3}", ms[kernel_column(Kernel::NodeUpdateFinal)]));
        println!("| {name} | {contacts} | {ns:.1} | {:.1}x | {gpu_ms} |", reference / ns);
    }
    if gpu.is_some_and(|gpu| gpu.is_software()) {
        println!("\nThe GPU here is a software adapter: its column is left out.");
    }
}
