//! The sections `self_contact`, `self_contact_crossed_gpu` and `self_contact_gpu`: a cloth
//! folding over a bar, two cloths on the bunny and two cloths started crossed (on the CPU, then
//! on the GPU), checked with an exact triangle-triangle test, and the cost.

use super::*;

/// The self-contact sections' contact: 8 mm thick, friction 0.3.
pub(crate) const SELF_CONTACT: SelfContact = SelfContact { thickness: 0.008, friction: 0.3 };

/// Self-contact on the CPU: two scenes, each with and without contact, checked at the end by an
/// exact triangle–triangle test between every two triangles sharing no corner and by the least
/// distance between particles sharing no spring; then two cloths started crossed
/// ([`started_crossed`]); then the cost of contact in a tick of a 128 x 128 cloth.
pub(crate) fn self_contact(bunny: &ObjMesh, single: &rayon::ThreadPool, threads: usize) {
    const THICKNESS: f32 = SELF_CONTACT.thickness;
    const SECONDS: f32 = 3.0;
    let contact = SELF_CONTACT;
    println!("\n## Self-contact: a cloth folding over a bar, two cloths on the bunny (CPU, {threads} threads)\n");
    println!(
        "Thickness {} mm, friction 0.3, block descent at Looper 16, {SECONDS} s of 60 Hz ticks. Crossing triangles: pairs of triangles sharing no corner (within a cloth) or of two cloths that intersect, by an exact segment–triangle test of each edge. Close pairs: particles sharing no spring, lying farther apart than the thickness in the rest shape, closer than half the thickness at the end.\n",
        THICKNESS * 1e3
    );
    println!(
        "| scene | contact | crossing triangles within a cloth | between the cloths | close pairs | ms per tick |"
    );
    println!("|---|---|---|---|---|---|");
    let bar = Collider::primitive(Primitive::Capsule { radius: 0.03, half_length: 1.0 })
        .expect("a valid capsule")
        .with_pose(ColliderPose { rotation: Quat::from_rotation_x(std::f32::consts::FRAC_PI_2), ..Default::default() })
        .with_friction(0.5);
    let fold = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(64))).expect("a valid grid"));
    for on in [true, false] {
        let params = ClothParams {
            self_contact: on.then_some(contact),
            integrator: Integrator::BLOCK_DESCENT,
            ..Default::default()
        };
        // From 0.8 m the two sides whip into each other under the bar; from lower they only
        // swing down.
        let pose = Affine3A::from_translation(Vec3::new(0.12, 0.8, 0.0));
        let mut sim = ClothSim::new(params, Arc::clone(&fold), pose, &[]).expect("a valid cloth");
        let ticks = (SECONDS / TICK).round() as u32;
        let seconds = time(|| {
            for _ in 0..ticks {
                sim.tick(TICK, std::slice::from_ref(&bar));
            }
        });
        let x = sim.positions();
        println!(
            "| 64 x 64 (1 m) over a bar of radius 3 cm | {} | {} | — | {} | {:.2} |",
            if on { "on" } else { "off" },
            crossing_triangles(&fold, &x, None),
            close_pairs(&fold, &x, None, 0.5 * THICKNESS),
            seconds * 1e3 / ticks as f64
        );
    }
    let surface = collider(bunny, 5).with_exact_contact(bunny.as_mesh_ref()).expect("the bunny has area");
    let two = Arc::new(ClothTopology::grid(square_grid(64)).expect("a valid grid"));
    let top = bvh_cloth_bench::top_of(&surface);
    for on in [true, false] {
        let params = ClothParams {
            self_contact: on.then_some(contact),
            integrator: Integrator::BLOCK_DESCENT,
            ..Default::default()
        };
        let place = |lift: f32, turn: f32| {
            Affine3A::from_rotation_translation(Quat::from_rotation_y(turn), Vec3::new(-0.1, top + lift, 0.0))
        };
        let mut lower = ClothSim::new(params.clone(), Arc::clone(&two), place(0.2, 0.0), &[]).expect("a valid cloth");
        let mut upper = ClothSim::new(params, Arc::clone(&two), place(0.35, 0.5), &[]).expect("a valid cloth");
        let mut solver = ContactSolver::default();
        let ticks = (SECONDS / TICK).round() as u32;
        let seconds = time(|| {
            for _ in 0..ticks {
                ClothSim::tick_together(
                    &mut [&mut lower, &mut upper],
                    TICK,
                    std::slice::from_ref(&surface),
                    &mut solver,
                );
            }
        });
        let (a, b) = (lower.positions(), upper.positions());
        let within = crossing_triangles(&two, &a, None) + crossing_triangles(&two, &b, None);
        let between = crossing_triangles(&two, &a, Some((&two, &b)));
        let close = close_pairs(&two, &a, None, 0.5 * THICKNESS)
            + close_pairs(&two, &b, None, 0.5 * THICKNESS)
            + close_pairs(&two, &a, Some(&b), 0.5 * THICKNESS);
        println!(
            "| two 64 x 64 (1.4 m) dropped on each other onto the bunny (exact contact) | {} | {within} | {between} | {close} | {:.2} |",
            if on { "on" } else { "off" },
            seconds * 1e3 / ticks as f64
        );
    }

    started_crossed(&surface);

    println!("\n### Cost: a 128 x 128 cloth (1.4 m) resting on the bunny\n");
    println!(
        "The cloth falls 1 s with self-contact, then the same state ticks with and without it, alternating, best of 5 each (ms per 60 Hz tick, Looper 16).\n"
    );
    let (surface, with) = resting_with_self_contact(bunny);
    let own = crossing_triangles(with.topology(), &with.positions(), None);
    let close = close_pairs(with.topology(), &with.positions(), None, 0.5 * THICKNESS);
    println!(
        "After its fall with contact the cloth has {own} pairs of its own triangles intersecting and {close} close pairs of particles.\n"
    );
    println!("| threads | tick without contact ms | tick with contact ms | contact / rest of the tick |");
    println!("|---|---|---|---|");
    let mut without = with.clone();
    without.set_params(ClothParams { self_contact: None, ..with.params().clone() }).expect("valid parameters");
    print_with_and_without(single, threads, &without, &with, std::slice::from_ref(&surface), 5);
}

/// Two 32 x 32 cloths (1 m) that start crossed along a line, dropped onto the bunny: one flat,
/// the other through it at 10 degrees about the line across both middles. Prints the pairs of
/// triangles between them that intersect, and the closest pair of particles, at the start and
/// every half second for 1 s, with self-contact and without.
fn started_crossed(surface: &Collider) {
    println!("\n### Two cloths started crossed\n");
    println!(
        "Two 32 x 32 cloths (1 m), one flat 0.2 m above the bunny, the other turned 10 degrees about the line across both middles, so that they cross along it; both fall onto the bunny (exact contact) together (`ClothSim::tick_together`). Between them: the intersecting triangle pairs and the closest pair of particles.\n"
    );
    println!("| contact | pairs at 0 s | at 0.5 s | at 1 s | closest pair at 1 s mm | close pairs at 1 s |");
    println!("|---|---|---|---|---|---|");
    for on in [true, false] {
        let [mut a, mut b] = crossed_cloths(surface, on);
        let grid = Arc::clone(a.topology());
        let between =
            |a: &ClothSim, b: &ClothSim| crossing_triangles(&grid, &a.positions(), Some((&grid, &b.positions())));
        let mut pairs = vec![between(&a, &b)];
        let mut solver = ContactSolver::default();
        for _ in 0..2 {
            for _ in 0..30 {
                ClothSim::tick_together(&mut [&mut a, &mut b], TICK, std::slice::from_ref(surface), &mut solver);
            }
            pairs.push(between(&a, &b));
        }
        let label = if on { "on" } else { "off" };
        print_crossed_row(label, &grid, &pairs, &a.positions(), &b.positions());
    }
}

/// The two 32 x 32 cloths (1 m) of [`started_crossed`] over `surface`, block descent, with
/// self-contact when `contact`: one flat 0.2 m above the surface's top, the other turned 10
/// degrees about the line across both middles.
fn crossed_cloths(surface: &Collider, contact: bool) -> [ClothSim; 2] {
    let top = bvh_cloth_bench::top_of(surface);
    let grid = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(32))).expect("a valid grid"));
    let params = ClothParams {
        self_contact: contact.then_some(SELF_CONTACT),
        integrator: Integrator::BLOCK_DESCENT,
        ..Default::default()
    };
    let middle = Vec3::new(-0.1, top + 0.2, 0.0);
    let turned = Affine3A::from_rotation_translation(Quat::from_rotation_z(10f32.to_radians()), middle);
    [Affine3A::from_translation(middle), turned]
        .map(|pose| ClothSim::new(params.clone(), Arc::clone(&grid), pose, &[]).expect("a valid cloth"))
}

/// One row of the started-crossed tables: `label`, the pairs at 0, 0.5 and 1 s, and the closest
/// pair and the close pairs between the cloths at `x` and `y` (each of shape `grid`) at 1 s.
fn print_crossed_row(label: &str, grid: &ClothTopology, pairs: &[usize], x: &[Vec3], y: &[Vec3]) {
    let closest = x.iter().flat_map(|p| y.iter().map(move |q| p.distance(*q))).fold(f32::INFINITY, f32::min);
    println!(
        "| {label} | {} | {} | {} | {:.2} | {} |",
        pairs[0],
        pairs[1],
        pairs[2],
        closest * 1e3,
        close_pairs(grid, x, Some(y), 0.5 * SELF_CONTACT.thickness)
    );
}

/// The two cloths started crossed of [`started_crossed`] on the GPU, with contact (the
/// `self_contact_crossed_gpu` section): the untangling kernels against the CPU's analysis.
pub(crate) fn started_crossed_on_gpu(bunny: &ObjMesh, gpu: Option<&Gpu>) {
    println!("\n### Two cloths started crossed, on the GPU\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter.");
        return;
    };
    println!(
        "The two cloths of the table above, with contact, in one batch on the GPU (`untangle.wgsl` finds what lies through the other); the bunny's exact surface as above.\n"
    );
    println!("| adapter | pairs at 0 s | at 0.5 s | at 1 s | closest pair at 1 s mm | close pairs at 1 s |");
    println!("|---|---|---|---|---|---|");
    let surface = collider(bunny, 5).with_exact_contact(bunny.as_mesh_ref()).expect("the bunny has area");
    let cloths = crossed_cloths(&surface, true);
    let grid = Arc::clone(cloths[0].topology());
    let gpu_colliders = GpuColliders::new(&gpu.device, std::slice::from_ref(&surface));
    let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
    let ids = cloths.each_ref().map(|cloth| {
        let id = batch.insert(&gpu.device, &gpu.queue, cloth).expect("the cloth fits the device");
        batch.set_params(&gpu.queue, id, cloth.params(), TICK);
        id
    });
    let positions = |batch: &ClothBatch| {
        ids.map(|id| {
            let particles = particles_on_gpu(gpu, batch, id);
            particles.iter().map(|p| Vec3::from_slice(&p.position[..3])).collect::<Vec<Vec3>>()
        })
    };
    let between = |[x, y]: &[Vec<Vec3>; 2]| crossing_triangles(&grid, x, Some((&grid, y)));
    let mut pairs = vec![between(&cloths.each_ref().map(|c| c.positions()))];
    for _ in 0..2 {
        batch.prepare(&gpu.device, &gpu.queue, &gpu.kernels, &gpu_colliders);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        batch.encode_ticks(&mut encoder, &gpu.kernels, 30);
        gpu.queue.submit([encoder.finish()]);
        pairs.push(between(&positions(&batch)));
    }
    let [x, y] = positions(&batch);
    print_crossed_row(&gpu.info.name, &grid, &pairs, &x, &y);
}

/// The self-contact cost scene: the bunny at n = 5 with its exact surface, and a 128 x 128
/// cloth (1.4 m) after falling onto it for 1 s with self-contact.
pub(crate) fn resting_with_self_contact(bunny: &ObjMesh) -> (Collider, ClothSim) {
    let surface = collider(bunny, 5).with_exact_contact(bunny.as_mesh_ref()).expect("the bunny has area");
    let top = bvh_cloth_bench::top_of(&surface);
    let big = Arc::new(ClothTopology::grid(square_grid(128)).expect("a valid grid"));
    let params =
        ClothParams { self_contact: Some(SELF_CONTACT), integrator: Integrator::BLOCK_DESCENT, ..Default::default() };
    let mut with = ClothSim::new(params, big, Affine3A::from_translation(Vec3::new(-0.1, top + 0.2, 0.0)), &[])
        .expect("a valid cloth");
    for _ in 0..(1.0 / TICK).round() as u32 {
        with.tick(TICK, std::slice::from_ref(&surface));
    }
    (surface, with)
}

/// Self-contact's cost on the GPU (the `self_contact_gpu` section, after `self_contact`).
pub(crate) fn self_contact_on_gpu(bunny: &ObjMesh, gpu: Option<&Gpu>) {
    println!("\n### Cost on the GPU: the same 128 x 128 cloth\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter.");
        return;
    };
    println!(
        "From the state above, one more second on the GPU, then GPU ms per tick by timestamp queries, each dispatch in a compute pass of its own, median of 9 ticks: the self-contact and untangling kernels against everything else.\n"
    );
    println!("| adapter | self-contact ms | rest of the tick ms | self-contact / rest |");
    println!("|---|---|---|---|");
    let (surface, with) = resting_with_self_contact(bunny);
    let kernels = [
        Kernel::ContactBegin,
        Kernel::ContactCount,
        Kernel::ContactScan,
        Kernel::ContactScatter,
        Kernel::ContactFind,
        Kernel::ContactApply,
        Kernel::ContactFindEdges,
        Kernel::Untangle,
    ];
    print_kernel_share(gpu, &surface, &with, Kernel::ContactFind, &kernels);
}

/// Pairs of intersecting triangles: within `topology`'s cloth at `x` (pairs sharing no corner),
/// or between it and `other`'s cloth.
pub(crate) fn crossing_triangles(
    topology: &ClothTopology,
    x: &[Vec3],
    other: Option<(&ClothTopology, &[Vec3])>,
) -> usize {
    crossing_pairs(topology.triangles(), x, other.map(|(t, y)| (t.triangles(), y)))
}

/// Pairs of particles closer than `limit`: within `topology`'s cloth at `x` (sharing no spring
/// and lying farther apart than the limit's double in the rest shape), or between it and
/// `other` (a cloth of the same topology).
pub(crate) fn close_pairs(topology: &ClothTopology, x: &[Vec3], other: Option<&[Vec3]>, limit: f32) -> usize {
    let rest = topology.rest_positions();
    (0..x.len())
        .into_par_iter()
        .map(|i| match other {
            Some(y) => y.iter().filter(|q| x[i].distance(**q) < limit).count(),
            None => (i + 1..x.len())
                .filter(|&j| {
                    x[i].distance(x[j]) < limit
                        && rest[i].distance(rest[j]) >= 2.0 * limit
                        && !topology.springs_of(i).iter().any(|e| e.other as usize == j)
                })
                .count(),
        })
        .sum()
}
