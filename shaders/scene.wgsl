// tumble's scene shader: instanced rigid bodies (opaque, or translucent ghosts of a compared
// world), lines (grid, constraints, contacts), the ground plane, and the bodies' depth seen from
// the key light for its shadow map. A compute entry point runs the very same body transform so
// tests can read back the vertices the vertex shader computes.

struct Globals {
    view_proj: mat4x4<f32>,
    // World to the shadow map's clip space (orthographic, from the key light).
    light_view_proj: mat4x4<f32>,
    // xyz: unit direction towards the key light; w: 1 for flat (unlit) shading.
    light: vec4<f32>,
    // xyz: camera position.
    eye: vec4<f32>,
    // x: 1 with shadows; y: one shadow-map texel in texture coordinates; z: normal offset of
    // the lookup in world units.
    shadow: vec4<f32>,
};

// Pipelines drawing without shadows set this to false: the lookup is compiled out.
override SHADOWS: bool = true;

@group(0) @binding(0) var<uniform> globals: Globals;
@group(1) @binding(0) var shadow_map: texture_depth_2d;
@group(1) @binding(1) var shadow_sampler: sampler_comparison;

// How much of the key light reaches `world` (0 in shadow .. 1 lit), filtered over 3x3 shadow-map
// texels around the point, looked up a little along the normal `n` against acne.
fn lit_fraction(world: vec3<f32>, n: vec3<f32>) -> f32 {
    if !SHADOWS || globals.shadow.x < 0.5 {
        return 1.0;
    }
    let clip = globals.light_view_proj * vec4<f32>(world + n * globals.shadow.z, 1.0);
    let ndc = clip.xyz / clip.w;
    let uv = vec2<f32>(0.5 + 0.5 * ndc.x, 0.5 - 0.5 * ndc.y);
    if any(uv < vec2<f32>(0.0)) || any(uv > vec2<f32>(1.0)) || ndc.z > 1.0 {
        return 1.0;
    }
    // Four bilinear comparisons half a texel apart: a tent filter over 3x3 texels.
    let h = 0.5 * globals.shadow.y;
    var sum = textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(-h, -h), ndc.z);
    sum += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(h, -h), ndc.z);
    sum += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(-h, h), ndc.z);
    sum += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(h, h), ndc.z);
    return 0.25 * sum;
}

// The core's rotation, glam's `DQuat * DVec3`, term for term in f32:
// v (w^2 - b.b) + b (2 v.b) + (b x v)(2 w), with q = (b, w).
fn rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let b = q.xyz;
    let w = q.w;
    return v * (w * w - dot(b, b)) + b * (dot(v, b) * 2.0) + cross(b, v) * (w * 2.0);
}

// The coursework's currV: R(q) origV + COM.
fn body_point(q: vec4<f32>, com: vec3<f32>, local: vec3<f32>) -> vec3<f32> {
    return rotate(q, local) + com;
}

struct BodyVertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
};

struct Instance {
    @location(2) rotation: vec4<f32>,
    // xyz: centre of mass; w unused.
    @location(3) com: vec4<f32>,
    // rgb: linear colour; a: highlight (0 or 1).
    @location(4) color: vec4<f32>,
};

struct BodyOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) world: vec3<f32>,
};

@vertex
fn vs_body(v: BodyVertex, inst: Instance) -> BodyOut {
    let world = body_point(inst.rotation, inst.com.xyz, v.position);
    var out: BodyOut;
    out.clip = globals.view_proj * vec4<f32>(world, 1.0);
    out.normal = rotate(inst.rotation, v.normal);
    out.color = inst.color;
    out.world = world;
    return out;
}

// A body's colour under the key light (reaching it by `lit`), the camera's fill light and the
// hemisphere ambient.
fn shade_body(in: BodyOut, lit: f32) -> vec3<f32> {
    let n = normalize(in.normal);
    let l = globals.light.xyz;
    let to_eye = normalize(globals.eye.xyz - in.world);
    let key = max(dot(n, l), 0.0) * lit;
    // Fill light from the camera, so faces turned away from the key light keep their shape.
    let fill = max(dot(n, to_eye), 0.0);
    // Hemisphere ambient: a little brighter from the sky than from the ground.
    let ambient = mix(0.12, 0.24, 0.5 + 0.5 * n.y);
    var c = in.color.rgb * (ambient + 0.75 * key + 0.25 * fill);
    let h = normalize(l + to_eye);
    c += vec3<f32>(0.12) * pow(max(dot(n, h), 0.0), 40.0) * step(0.0, dot(n, l)) * lit;
    // Picked body: tint towards warm white.
    return mix(c, vec3<f32>(1.0, 0.85, 0.4), in.color.a * 0.45);
}

@fragment
fn fs_body(in: BodyOut) -> @location(0) vec4<f32> {
    if globals.light.w > 0.5 {
        return vec4<f32>(in.color.rgb, 1.0);
    }
    return vec4<f32>(shade_body(in, lit_fraction(in.world, normalize(in.normal))), 1.0);
}

// A compared world over the first: lighter, translucent, casting and receiving no shadow.
@fragment
fn fs_ghost(in: BodyOut) -> @location(0) vec4<f32> {
    let c = mix(shade_body(in, 1.0), vec3<f32>(1.0), 0.25);
    return vec4<f32>(c, 0.4);
}

// Bodies seen from the key light, for its shadow map.
@vertex
fn vs_shadow(v: BodyVertex, inst: Instance) -> @builtin(position) vec4<f32> {
    return globals.light_view_proj * vec4<f32>(body_point(inst.rotation, inst.com.xyz, v.position), 1.0);
}

struct LineVertex {
    @location(0) position: vec3<f32>,
    @location(1) color: vec4<f32>,
};

// Lines and the ground: a colour per vertex; the world position is for the ground's shadow.
struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec4<f32>,
    @location(1) world: vec3<f32>,
};

@vertex
fn vs_line(v: LineVertex) -> LineOut {
    var out: LineOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.color = v.color;
    out.world = v.position;
    return out;
}

@fragment
fn fs_line(in: LineOut) -> @location(0) vec4<f32> {
    return in.color;
}

// The ground plane and grid: their own colour where the key light reaches, darker in shadow.
@fragment
fn fs_ground(in: LineOut) -> @location(0) vec4<f32> {
    if globals.light.w > 0.5 {
        return in.color;
    }
    let lit = lit_fraction(in.world, vec3<f32>(0.0, 1.0, 0.0));
    return vec4<f32>(in.color.rgb * mix(0.45, 1.0, lit), in.color.a);
}

// ---- Readback of the body transform (tests) ----

struct InstanceData {
    rotation: vec4<f32>,
    com: vec4<f32>,
    color: vec4<f32>,
};

struct CheckParams {
    vertex_count: u32,
    first_instance: u32,
    instance_count: u32,
    pad: u32,
};

// The mesh's vertex buffer itself: 6 floats (position, normal) per vertex.
@group(0) @binding(1) var<storage, read> check_vertices: array<f32>;
@group(0) @binding(2) var<storage, read> check_instances: array<InstanceData>;
@group(0) @binding(3) var<storage, read_write> check_out: array<f32>;
@group(0) @binding(4) var<uniform> check_params: CheckParams;

@compute @workgroup_size(64)
fn cs_body_points(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = id.x;
    if index >= check_params.vertex_count * check_params.instance_count {
        return;
    }
    let inst = check_instances[check_params.first_instance + index / check_params.vertex_count];
    let vi = index % check_params.vertex_count;
    let local = vec3<f32>(check_vertices[6u * vi], check_vertices[6u * vi + 1u], check_vertices[6u * vi + 2u]);
    let p = body_point(inst.rotation, inst.com.xyz, local);
    check_out[3u * index] = p.x;
    check_out[3u * index + 1u] = p.y;
    check_out[3u * index + 2u] = p.z;
}
