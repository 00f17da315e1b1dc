// Mesh shader: per-vertex sRGB colour times a texture sampled per pixel (mipmapped, an sRGB
// texture so the sample is linear; a 1x1 white one for untextured meshes), headlight Lambert
// shading, optional wireframe pass.
//
// Colours arrive in sRGB [0,1] and are decoded per vertex; shading happens in linear light and
// the render target (an sRGB view of the texture egui samples as Rgba8Unorm) encodes on store,
// so no fragment pays for a `pow`.

struct Uniforms {
    view_proj: mat4x4<f32>,
    // xyz: camera position (world), w: wireframe depth pull (clip-space z offset factor)
    eye: vec4<f32>,
    // rgb: wireframe colour, a: ambient term
    wire: vec4<f32>,
    // Weights of the result (over grey), the paint layer and the mask layer; w unused.
    layers: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;
@group(1) @binding(0) var base_tex: texture_2d<f32>;
@group(1) @binding(1) var base_samp: sampler;
// Paint over the base (sRGB colour, coverage), a 1x1 transparent texture when there is none.
@group(1) @binding(2) var paint_tex: texture_2d<f32>;
// The mask over the paint, the same way.
@group(1) @binding(3) var mask_tex: texture_2d<f32>;
// A hidden result shows this grey (0.75 sRGB, linear).
const HIDDEN_RESULT: f32 = 0.5225;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
    @location(3) uv: vec2<f32>,
};

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

@vertex
fn vs_main(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(3) uv: vec2<f32>,
    @location(2) color: vec3<f32>,
) -> VsOut {
    var out: VsOut;
    out.clip = u.view_proj * vec4<f32>(position, 1.0);
    out.world = position;
    out.normal = normal;
    out.color = srgb_to_linear(color);
    out.uv = uv;
    return out;
}

// A texel layer at `uv` (repeating outside [0, 1], edges clamped): bilinear over its four
// nearest texels with the colours weighted by coverage, so an unpainted texel beside a painted
// one lowers the coverage but never darkens the colour. Linear colour, coverage in alpha.
fn paint_at(tex: texture_2d<f32>, uv: vec2<f32>) -> vec4<f32> {
    let dim = vec2<i32>(textureDimensions(tex));
    let inside = (uv >= vec2<f32>(0.0)) & (uv <= vec2<f32>(1.0));
    let p = select(fract(uv), uv, inside) * vec2<f32>(dim) - 0.5;
    let i = vec2<i32>(floor(p));
    let f = p - floor(p);
    var acc = vec4<f32>(0.0);
    for (var k = 0; k < 4; k = k + 1) {
        let o = vec2<i32>(k & 1, k >> 1u);
        let q = clamp(i + o, vec2<i32>(0), dim - 1);
        let t = textureLoad(tex, q, 0);
        let w = select(1.0 - f.x, f.x, o.x == 1) * select(1.0 - f.y, f.y, o.y == 1) * t.a;
        acc = acc + vec4<f32>(t.rgb * w, w);
    }
    if (acc.a <= 0.0) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(acc.rgb / acc.a, acc.a);
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    // Headlight: the light sits at the eye, so the Lambert term is |n . v| (two-sided).
    let v = normalize(u.eye.xyz - in.world);
    var n = in.normal;
    let len = length(n);
    var lambert = 1.0;
    if (len > 1e-12) {
        n = n / len;
        lambert = abs(dot(n, v));
    }
    let ambient = u.wire.a;
    let result = in.color * textureSample(base_tex, base_samp, in.uv).rgb;
    let under = mix(vec3<f32>(HIDDEN_RESULT), result, u.layers.x);
    let paint = paint_at(paint_tex, in.uv);
    let painted = mix(under, paint.rgb, paint.a * u.layers.y);
    let mask = paint_at(mask_tex, in.uv);
    let base = mix(painted, mask.rgb, mask.a * u.layers.z);
    return vec4<f32>(base * (ambient + (1.0 - ambient) * lambert), 1.0);
}

@vertex
fn vs_wire(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(3) uv: vec2<f32>,
    @location(2) color: vec3<f32>,
) -> VsOut {
    var out: VsOut;
    var clip = u.view_proj * vec4<f32>(position, 1.0);
    // Pull lines slightly towards the camera so they win the depth test against their faces.
    clip.z = clip.z - u.eye.w * clip.w;
    out.clip = clip;
    out.world = position;
    out.normal = normal;
    out.color = color;
    out.uv = uv;
    return out;
}

@fragment
fn fs_wire(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(srgb_to_linear(u.wire.rgb), 0.45);
}

// Correspondence markers: instanced unit spheres, shaded with the same headlight. A rim marks the
// selected marker (white) or a source point waiting for its target (yellow).

struct MarkerOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
    @location(3) rim: f32,
};

@vertex
fn vs_marker(
    @location(0) unit: vec3<f32>,
    @location(1) center_radius: vec4<f32>,
    @location(2) color_rim: vec4<f32>,
) -> MarkerOut {
    var out: MarkerOut;
    let world = center_radius.xyz + unit * center_radius.w;
    out.clip = u.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.normal = unit;
    out.color = srgb_to_linear(color_rim.rgb);
    out.rim = color_rim.a;
    return out;
}

fn marker_color(in: MarkerOut) -> vec3<f32> {
    let v = normalize(u.eye.xyz - in.world);
    let facing = abs(dot(normalize(in.normal), v));
    var c = in.color * (0.35 + 0.65 * facing);
    // Outline of the sphere's silhouette: dark, or the rim colour when selected / pending.
    if (facing < 0.45) {
        if (in.rim > 1.5) {
            c = vec3<f32>(1.0, 0.85, 0.0);
        } else if (in.rim > 0.5) {
            c = vec3<f32>(1.0, 1.0, 1.0);
        } else if (facing < 0.25) {
            c = c * 0.25;
        }
    }
    return c;
}

@fragment
fn fs_marker(in: MarkerOut) -> @location(0) vec4<f32> {
    return vec4<f32>(marker_color(in), 1.0);
}

@fragment
fn fs_marker_ghost(in: MarkerOut) -> @location(0) vec4<f32> {
    return vec4<f32>(marker_color(in), 0.3);
}
