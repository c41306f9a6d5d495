// Item-buffer hemicube (Cohen & Greenberg 1985) on the GPU: every face of the half cube is
// drawn into its own viewport of one R32Uint atlas (top face res×res, then the four sides
// res×res/2), each pixel keeping the id of the nearest polygon. The CPU sums the delta form
// factors of the read-back ids, in the same order as the CPU hemicube (src/formfactor/hemicube.rs),
// so the two agree exactly wherever they rasterise the same ids.
//
// Face coordinates (X, Y, D) of a hemicube-local point (u, v, w), w along the normal, are
// those of `to_face` in hemicube.rs; a pixel's row counts down from the top of its viewport:
// top face row = (Y/D + 1)·res/2, side face row = (Y/D)·res/2. Depth is near/D (nearer is
// larger; the pipeline keeps the greater), which clips at D = near exactly like the CPU.

struct Face {
    // Hemicube origin, relative to the vertex positions' origin (xyz).
    origin: vec4<f32>,
    axis_u: vec4<f32>,
    axis_v: vec4<f32>,
    axis_w: vec4<f32>,
    // x: face index 0..4, y: near distance (bit-cast f32).
    params: vec4<u32>,
};

@group(0) @binding(0) var<uniform> face: Face;
// One entry per polygon: its id, 0xffffffff (blocks), or 0xfffffffe (not drawn).
@group(0) @binding(1) var<storage, read> ids: array<u32>;

const SKIP: u32 = 0xfffffffeu;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) id: u32,
};

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) polygon: u32) -> VertexOut {
    var out: VertexOut;
    let id = ids[polygon];
    out.id = id;
    if id == SKIP {
        // Outside the clip volume (z < 0): the whole triangle is discarded.
        out.clip = vec4<f32>(0.0, 0.0, -1.0, 1.0);
        return out;
    }
    let d = position - face.origin.xyz;
    let u = dot(d, face.axis_u.xyz);
    let v = dot(d, face.axis_v.xyz);
    let w = dot(d, face.axis_w.xyz);
    var p: vec3<f32>;
    switch face.params.x {
        case 0u: { p = vec3<f32>(u, v, w); }
        case 1u: { p = vec3<f32>(v, w, u); }
        case 2u: { p = vec3<f32>(-v, w, -u); }
        case 3u: { p = vec3<f32>(-u, w, v); }
        default: { p = vec3<f32>(u, w, -v); }
    }
    let near = bitcast<f32>(face.params.y);
    // NDC y points up while rows count down: top face ndc_y = −Y/D, sides ndc_y = 1 − 2Y/D.
    var y = -p.y;
    if face.params.x != 0u {
        y = p.z - 2.0 * p.y;
    }
    out.clip = vec4<f32>(p.x, y, near, p.z);
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) u32 {
    return in.id;
}
