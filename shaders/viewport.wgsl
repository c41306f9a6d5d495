// Nusselt viewport: radiosity solution drawn with per-vertex radiance.
//
// Radiance is linear (W m^-2 sr^-1 per channel). The egui-wgpu surface here is not sRGB,
// so the fragment shader applies exposure and encodes sRGB itself.
//
// Diffuse maps: a textured vertex carries its texture coordinates, the texture's mean over
// its elements (what the solver multiplied Kd by) and its layer + 1 in the texture array
// (0: untextured). With textures on, what is shown is E + (B - E) * texel / mean per
// channel, the solution's reflected light under the texel instead of the mean, as the CPU
// passes of `nusselt render` show it (`render::per_unit_texture`).

struct Uniforms {
    view_proj: mat4x4<f32>,
    // rgb: multiplier of the per-vertex display correction (1 with the ambient toggle on, 0 off);
    // w: exposure multiplier.
    ambient_exposure: vec4<f32>,
    // x: shooting patch, y: selected patch (0xffffffff = none), z: flags (bit 0: highlight
    // the shooter, bit 1: highlight the selection).
    ids: vec4<u32>,
    element_line_color: vec4<f32>,
    patch_line_color: vec4<f32>,
    // x: depth bias of lines in clip w units; y: 1 to show the diffuse maps, 0 not.
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;
// Linear RGBA diffuse maps, one per layer, mip-mapped; repeat wrap, trilinear filtering.
@group(0) @binding(1) var diffuse_maps: texture_2d_array<f32>;
@group(0) @binding(2) var diffuse_sampler: sampler;

struct MeshIn {
    @location(0) position: vec3<f32>,
    @location(1) patch_id: u32,
    @location(2) correction: vec3<f32>,
    @location(3) radiance: vec3<f32>,
    // OBJ texture coordinates (v = 0 at the image's bottom row).
    @location(4) uv: vec2<f32>,
    @location(5) mean: vec3<f32>,
    @location(6) layer: u32,
    @location(7) emission: vec3<f32>,
};

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) radiance: vec3<f32>,
    @location(1) @interpolate(flat) patch_id: u32,
    // Texture space with y down, as the layers are stored (top row first).
    @location(2) uv: vec2<f32>,
    @location(3) mean: vec3<f32>,
    @location(4) @interpolate(flat) layer: u32,
    @location(5) @interpolate(flat) emission: vec3<f32>,
};

@vertex
fn vs_mesh(v: MeshIn) -> MeshOut {
    var out: MeshOut;
    out.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    out.radiance = v.radiance + v.correction * u.ambient_exposure.rgb;
    out.patch_id = v.patch_id;
    out.uv = vec2<f32>(v.uv.x, 1.0 - v.uv.y);
    out.mean = v.mean;
    out.layer = v.layer;
    out.emission = v.emission;
    return out;
}

// texel / mean per channel; 1 where the mean is (nearly) black.
fn texture_ratio(texel: vec3<f32>, mean: vec3<f32>) -> vec3<f32> {
    let ok = mean >= vec3<f32>(1e-9);
    return select(vec3<f32>(1.0), texel / max(mean, vec3<f32>(1e-9)), ok);
}

fn linear_to_srgb(c: vec3<f32>) -> vec3<f32> {
    let x = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    let low = x * 12.92;
    let high = 1.055 * pow(x, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(high, low, x <= vec3<f32>(0.0031308));
}

@fragment
fn fs_mesh(v: MeshOut) -> @location(0) vec4<f32> {
    var radiance = v.radiance;
    // Sampled in uniform control flow (implicit derivatives); the per-vertex layer and the
    // uniform toggle only select its result.
    let layer = i32(max(v.layer, 1u) - 1u);
    let sampled = textureSample(diffuse_maps, diffuse_sampler, v.uv, layer);
    // A cut-out's hole (alpha below one half) is not a surface, textures shown or not.
    if (v.layer > 0u && sampled.a < 0.5) {
        discard;
    }
    if (u.params.y > 0.5) {
        let shown = v.emission + (radiance - v.emission) * texture_ratio(sampled.rgb, v.mean);
        radiance = select(radiance, shown, v.layer > 0u);
    }
    var c = linear_to_srgb(max(radiance, vec3<f32>(0.0)) * u.ambient_exposure.w);
    if ((u.ids.z & 1u) != 0u && v.patch_id == u.ids.x) {
        c = mix(c, vec3<f32>(1.0, 0.8, 0.1), 0.55);
    }
    if ((u.ids.z & 2u) != 0u && v.patch_id == u.ids.y) {
        c = mix(c, vec3<f32>(0.2, 0.55, 1.0), 0.4);
    }
    return vec4<f32>(c, 1.0);
}

struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) color: vec4<f32>,
};

// Element edges are drawn as instance 0, patch outlines as instance 1.
@vertex
fn vs_line(@location(0) position: vec3<f32>, @builtin(instance_index) line_set: u32) -> LineOut {
    var out: LineOut;
    var clip = u.view_proj * vec4<f32>(position, 1.0);
    // Pull lines slightly toward the eye so they win the depth test against their faces.
    clip.z = clip.z - u.params.x * clip.w;
    out.clip = clip;
    out.color = select(u.element_line_color, u.patch_line_color, line_set == 1u);
    return out;
}

@fragment
fn fs_line(v: LineOut) -> @location(0) vec4<f32> {
    return v.color;
}
