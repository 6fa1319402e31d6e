// NormalShader (Algorithm 3): per-vertex normals from the triangles around each particle,
// written with the positions into an interleaved vertex buffer (a mesh's vertex slab). One
// dispatch covers every cloth written into one vertex buffer, one thread per render vertex:
// the thread's owner names its cloth's BatchWriteback, which says where that cloth's vertices
// start among the group's threads.

#import bvh_cloth::types::{GpuParticle, BatchWriteback, WritebackGroup, thread_index}

@group(0) @binding(15) var<storage, read> writebacks: array<BatchWriteback>;
@group(0) @binding(16) var<storage, read> particles: array<GpuParticle>;
// Every cloth's surface (bvh_cloth_gpu::layout::gpu_surface_words) from its
// surface_start: the particle of each of the V vertices, N + 1 triangle offsets, the
// per-particle triangle lists, then three corners per triangle; particles relative to the
// cloth's first.
@group(0) @binding(17) var<storage, read> surface: array<u32>;
@group(0) @binding(18) var<storage, read_write> vertices: array<f32>;
// Per thread of every group: the index of the cloth (its BatchWriteback) the vertex belongs to.
@group(0) @binding(23) var<storage, read> owners: array<u32>;
@group(0) @binding(24) var<uniform> writeback_group: WritebackGroup;

fn corner(particle_start: u32, triangles: u32, t: u32, k: u32) -> vec3<f32> {
    return particles[particle_start + surface[triangles + 3u * t + k]].position.xyz;
}

@compute @workgroup_size(8, 8, 1)
fn normal_shader(@builtin(global_invocation_id) id: vec3<u32>) {
    let thread = thread_index(id, writeback_group.dispatch_width);
    if (thread >= writeback_group.vertex_count) {
        return;
    }
    let writeback = writebacks[owners[writeback_group.first_owner + thread]];
    let v = thread - writeback.group_first;
    let start = writeback.surface_start;
    let offsets = start + writeback.vertex_count;
    let lists = offsets + writeback.particle_count + 1u;
    let triangles = lists + surface[offsets + writeback.particle_count];
    let i = surface[start + v];
    // The CPU's order: the particle's triangles as listed (bvh_cloth_core::cloth::normals).
    var n = vec3<f32>(0.0);
    for (var k = surface[offsets + i]; k < surface[offsets + i + 1u]; k++) {
        let t = surface[lists + k];
        let a = corner(writeback.particle_start, triangles, t, 0u);
        n += cross(corner(writeback.particle_start, triangles, t, 1u) - a, corner(writeback.particle_start, triangles, t, 2u) - a);
    }
    var world_normal = vec3<f32>(0.0, 1.0, 0.0);
    let len2 = dot(n, n);
    if (len2 > 0.0 && len2 < 3.0e38) {
        world_normal = n * inverseSqrt(len2);
    }
    let p = particles[writeback.particle_start + i].position.xyz;
    let mesh = writeback.mesh;
    let local_position = (mesh.local_from_world * vec4(p, 1.0)).xyz;
    var local_normal = (mesh.normal_from_world * vec4(world_normal, 0.0)).xyz;
    let nl2 = dot(local_normal, local_normal);
    local_normal = select(vec3<f32>(0.0, 1.0, 0.0), local_normal * inverseSqrt(nl2), nl2 > 0.0);
    let w = mesh.first_word + v * mesh.stride_words;
    vertices[w + mesh.position_word] = local_position.x;
    vertices[w + mesh.position_word + 1u] = local_position.y;
    vertices[w + mesh.position_word + 2u] = local_position.z;
    vertices[w + mesh.normal_word] = local_normal.x;
    vertices[w + mesh.normal_word + 1u] = local_normal.y;
    vertices[w + mesh.normal_word + 2u] = local_normal.z;
}
