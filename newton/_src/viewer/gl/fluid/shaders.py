# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""GLSL sources of the screen-space fluid passes (OpenGL 3.3 core).

Conventions shared by every pass: eye space looks down -z, "depth" means the linear eye-space
distance ``-z_eye`` [m] and 0 marks a pixel without fluid; the fluid depth target is RG32F with
the batch index in G. Colours from the scene are display-referred (gamma 2.2); shading mixes
light in linear space and converts back.
"""

MAX_BATCHES = 16
# pixel budget of one filter tap line; wider blurs are cut at it
MAX_FILTER_RADIUS_PX = 32
# splats for the thickness pass are this much larger than the drawn ellipsoids, which fills the
# gaps between particles so that a body of fluid reads as one slab
THICKNESS_SPLAT_SCALE = 1.5

# Instanced screen-space quad of one ellipsoid: its exact projected bounding rectangle (Sigg,
# Weyrich, Botsch & Gross, "GPU-based ray-casting of quadratic surfaces", 2006), placed at the
# front of the ellipsoid's bounding sphere so that every ray-cast depth lies behind the quad
# (conservative depth keeps early depth rejection working).
ELLIPSOID_VERTEX = """
#version 330 core
layout(location = 0) in vec2 corner;
layout(location = 1) in vec4 center_radius;
layout(location = 2) in vec4 axis1;
layout(location = 3) in vec4 axis2;
layout(location = 4) in vec4 axis3;

uniform mat4 view;
uniform mat4 projection;
uniform float radius_scale;
uniform float splat_scale;

out vec3 v_ray;
flat out vec3 v_center;
flat out mat3 v_to_unit;
flat out float v_volume_share;

// interval of one clip coordinate (row) over the unit sphere mapped by T, in NDC
vec2 projected_interval(vec4 row, vec4 row_w)
{
    const vec4 q = vec4(1.0, 1.0, 1.0, -1.0);
    float a = dot(row, q * row_w);
    float b = dot(row_w, q * row_w);
    float c = dot(row, q * row);
    float h = sqrt(max(a * a - b * c, 0.0));
    vec2 x = vec2(a - h, a + h) / b;
    return vec2(min(x.x, x.y), max(x.x, x.y));
}

void main()
{
    mat3 rot = mat3(view);
    float r = center_radius.w * radius_scale * splat_scale;
    vec3 s = r * max(vec3(axis1.w, axis2.w, axis3.w), vec3(1.0e-3));
    vec3 e1 = normalize(rot * axis1.xyz);
    vec3 e2 = normalize(rot * axis2.xyz);
    vec3 e3 = normalize(rot * axis3.xyz);
    v_to_unit = mat3(1.0 / s.x, 0.0, 0.0, 0.0, 1.0 / s.y, 0.0, 0.0, 0.0, 1.0 / s.z) * transpose(mat3(e1, e2, e3));

    // a particle of radius r stands for a cube of fluid of edge 2r: chords are scaled so that the
    // splats of a lattice integrate to its volume
    float base = center_radius.w;
    v_volume_share = 8.0 * base * base * base / (4.18879020479 * s.x * s.y * s.z);

    vec3 c = (view * vec4(center_radius.xyz, 1.0)).xyz;
    v_center = c;
    float bound = max(s.x, max(s.y, s.z));
    float near = projection[3][2] / (projection[2][2] - 1.0);
    float front = -(c.z + bound);
    if (front <= near) {
        // reaches the near plane (or the eye): dropped rather than clipped into a wrong shape
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        v_ray = vec3(0.0);
        return;
    }
    mat4 t = projection * mat4(vec4(e1 * s.x, 0.0), vec4(e2 * s.y, 0.0), vec4(e3 * s.z, 0.0), vec4(c, 1.0));
    vec4 row_w = vec4(t[0][3], t[1][3], t[2][3], t[3][3]);
    vec2 bx = projected_interval(vec4(t[0][0], t[1][0], t[2][0], t[3][0]), row_w);
    vec2 by = projected_interval(vec4(t[0][1], t[1][1], t[2][1], t[3][1]), row_w);
    vec2 ndc = vec2(mix(bx.x, bx.y, 0.5 + 0.5 * corner.x), mix(by.x, by.y, 0.5 + 0.5 * corner.y));
    v_ray = vec3(ndc.x / projection[0][0], ndc.y / projection[1][1], -1.0);
    gl_Position = vec4(ndc * front, projection[2][2] * -front + projection[3][2], front);
}
"""

# Solves |M (t ray - c)| = 1 for the ray from the eye; shared by the depth and thickness passes.
_ELLIPSOID_HIT = """
in vec3 v_ray;
flat in vec3 v_center;
flat in mat3 v_to_unit;
flat in float v_volume_share;

uniform mat4 projection;

// entry and exit parameter of the ray t * v_ray; false when it misses
bool hit_ellipsoid(out float t0, out float t1)
{
    vec3 a = v_to_unit * v_ray;
    vec3 b = -(v_to_unit * v_center);
    float qa = dot(a, a);
    float qb = dot(a, b);
    float qc = dot(b, b) - 1.0;
    float disc = qb * qb - qa * qc;
    if (disc < 0.0)
        return false;
    float root = sqrt(disc);
    t0 = (-qb - root) / qa;
    t1 = (-qb + root) / qa;
    return t0 > 0.0;
}

float window_depth(vec3 p)
{
    vec4 clip = projection * vec4(p, 1.0);
    return clip.z / clip.w * 0.5 + 0.5;
}
"""

DEPTH_FRAGMENT = (
    """
#version 330 core
#extension GL_ARB_conservative_depth : enable
layout(depth_greater) out float gl_FragDepth;
"""
    + _ELLIPSOID_HIT
    + """
uniform float batch_index;
layout(location = 0) out vec2 out_depth;

void main()
{
    float t0, t1;
    if (!hit_ellipsoid(t0, t1))
        discard;
    vec3 p = t0 * v_ray;
    gl_FragDepth = window_depth(p);
    out_depth = vec2(-p.z, batch_index);
}
"""
)

THICKNESS_FRAGMENT = (
    """
#version 330 core
#extension GL_ARB_conservative_depth : enable
layout(depth_greater) out float gl_FragDepth;
"""
    + _ELLIPSOID_HIT
    + """
uniform vec3 absorption;
layout(location = 0) out vec4 out_optical;

void main()
{
    float t0, t1;
    if (!hit_ellipsoid(t0, t1))
        discard;
    gl_FragDepth = window_depth(t0 * v_ray);
    float chord = (t1 - t0) * length(v_ray) * v_volume_share;
    out_optical = vec4(absorption * chord, chord);
}
"""
)

FULLSCREEN_VERTEX = """
#version 330 core
out vec2 v_uv;
void main()
{
    // one triangle covering the screen
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    v_uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

# The scene's window depth as a float colour target: the compute passes read it back through a
# pixel buffer, and reading a depth format back is slow on some drivers (2.6 ms at 720p on an H100)
DEPTH_COPY_FRAGMENT = """
#version 330 core
uniform sampler2D scene_depth_tex;
layout(location = 0) out float out_depth;
void main()
{
    out_depth = texelFetch(scene_depth_tex, ivec2(gl_FragCoord.xy), 0).r;
}
"""

# Separable bilateral filter of the linear depth: spatial Gaussian whose width is blur_radius
# in world units projected at the pixel's depth, times a range Gaussian in depth (four times as
# wide); pixels of other batches and empty pixels do not contribute.
FILTER_FRAGMENT = f"""
#version 330 core
#define MAX_BATCHES {MAX_BATCHES}
in vec2 v_uv;
uniform sampler2D depth_tex;
uniform vec2 direction;
uniform float focal_px;
uniform int max_radius_px;
uniform float blur_radius[MAX_BATCHES];
layout(location = 0) out vec2 out_depth;

void main()
{{
    ivec2 pix = ivec2(gl_FragCoord.xy);
    vec2 center = texelFetch(depth_tex, pix, 0).rg;
    if (center.r <= 0.0) {{
        out_depth = center;
        return;
    }}
    int batch = int(center.g + 0.5);
    float world = blur_radius[batch];
    float sigma_px = world * focal_px / center.r;
    if (world <= 0.0 || sigma_px < 0.5) {{
        out_depth = center;
        return;
    }}
    int radius = min(int(ceil(2.0 * sigma_px)), max_radius_px);
    float inv_2s2 = 0.5 / (sigma_px * sigma_px);
    // the range term only has to keep apart surfaces that overlap on screen, which are far
    // apart in depth; a narrow one would stop the smoothing of slanted faces
    float range = 4.0 * world;
    float inv_2r2 = 0.5 / (range * range);
    ivec2 size = textureSize(depth_tex, 0);
    float sum = 0.0;
    float wsum = 0.0;
    for (int k = -radius; k <= radius; ++k) {{
        float offset = float(k);
        ivec2 q = clamp(pix + ivec2(direction * offset), ivec2(0), size - 1);
        vec2 s = texelFetch(depth_tex, q, 0).rg;
        if (s.r <= 0.0 || int(s.g + 0.5) != batch)
            continue;
        float dz = s.r - center.r;
        float w = exp(-offset * offset * inv_2s2 - dz * dz * inv_2r2);
        sum += w * s.r;
        wsum += w;
    }}
    out_depth = vec2(sum / wsum, center.g);
}}
"""

# Separable Gaussian of the optical depth (kept at half resolution) with the width of the depth
# filter at the pixel's depth: it removes the ripple the splats of a lattice leave in the sum.
OPTICAL_FILTER_FRAGMENT = f"""
#version 330 core
#define MAX_BATCHES {MAX_BATCHES}
in vec2 v_uv;
uniform sampler2D optical_tex;
uniform sampler2D depth_tex;
uniform int depth_step;
uniform vec2 direction;
uniform float focal_px;
uniform int max_radius_px;
uniform float blur_radius[MAX_BATCHES];
layout(location = 0) out vec4 out_optical;

void main()
{{
    ivec2 pix = ivec2(gl_FragCoord.xy);
    vec4 center = texelFetch(optical_tex, pix, 0);
    vec2 s = texelFetch(depth_tex, pix * depth_step, 0).rg;
    float world = s.r > 0.0 ? blur_radius[int(s.g + 0.5)] : 0.0;
    float sigma_px = s.r > 0.0 ? world * focal_px / s.r : 0.0;
    if (sigma_px < 0.5) {{
        out_optical = center;
        return;
    }}
    int radius = min(int(ceil(2.0 * sigma_px)), max_radius_px);
    float inv_2s2 = 0.5 / (sigma_px * sigma_px);
    ivec2 size = textureSize(optical_tex, 0);
    vec4 sum = vec4(0.0);
    float wsum = 0.0;
    for (int k = -radius; k <= radius; ++k) {{
        float offset = float(k);
        ivec2 q = clamp(pix + ivec2(direction * offset), ivec2(0), size - 1);
        float w = exp(-offset * offset * inv_2s2);
        sum += w * texelFetch(optical_tex, q, 0);
        wsum += w;
    }}
    out_optical = sum / wsum;
}}
"""

SHADE_FRAGMENT = f"""
#version 330 core
#define MAX_BATCHES {MAX_BATCHES}
in vec2 v_uv;
uniform sampler2D depth_tex;
uniform sampler2D optical_tex;
uniform sampler2D scene_tex;
uniform sampler2D env_tex;
uniform sampler2D shadow_tex;
uniform sampler2D scene_depth_tex;
uniform bool has_env;
uniform bool has_shadow;
uniform float env_intensity;
uniform mat4 projection;
uniform mat4 view;
uniform mat4 light_space;
uniform vec3 sun_dir_eye;
uniform vec3 sky_upper;
uniform vec3 sky_lower;
uniform int up_axis;
uniform vec2 inv_size;
uniform vec4 base_color[MAX_BATCHES];
uniform float ior[MAX_BATCHES];
uniform float reflectance[MAX_BATCHES];
uniform float specular_intensity[MAX_BATCHES];
uniform float specular_power[MAX_BATCHES];
layout(location = 0) out vec4 out_color;

const float PI = 3.14159265358979;

vec3 eye_position(vec2 uv, float depth)
{{
    // invert the projection for a point at linear depth `depth`
    vec2 ndc = uv * 2.0 - 1.0;
    return vec3(ndc.x * depth / projection[0][0], ndc.y * depth / projection[1][1], -depth);
}}

vec3 fetch_eye(ivec2 q, float fallback_depth, out bool valid)
{{
    vec2 s = texelFetch(depth_tex, q, 0).rg;
    valid = s.r > 0.0;
    return eye_position((vec2(q) + 0.5) * inv_size, valid ? s.r : fallback_depth);
}}

vec3 environment(vec3 dir_world)
{{
    vec3 d = dir_world;
    if (up_axis == 0) d = vec3(-d.y, d.x, d.z);
    else if (up_axis == 2) d = vec3(d.x, d.z, -d.y);
    if (has_env) {{
        float u = atan(d.z, d.x) / (2.0 * PI) + 0.5;
        float v = asin(clamp(d.y, -1.0, 1.0)) / PI + 0.5;
        return pow(textureLod(env_tex, vec2(u, v), 2.0).rgb, vec3(2.2)) * env_intensity;
    }}
    return pow(mix(sky_lower, sky_upper, clamp(d.y * 0.5 + 0.5, 0.0, 1.0)), vec3(2.2));
}}

float in_shadow(vec3 camera_to_point)
{{
    if (!has_shadow)
        return 0.0;
    vec4 l = light_space * vec4(camera_to_point, 1.0);
    vec3 p = l.xyz / l.w * 0.5 + 0.5;
    if (any(lessThan(p, vec3(0.0))) || any(greaterThan(p, vec3(1.0))))
        return 0.0;
    float occluded = 0.0;
    vec2 texel = 1.0 / vec2(textureSize(shadow_tex, 0));
    for (int i = -1; i <= 1; ++i)
        for (int j = -1; j <= 1; ++j)
            occluded += (p.z - 0.002 > texture(shadow_tex, p.xy + vec2(i, j) * texel).r) ? 1.0 : 0.0;
    return occluded / 9.0;
}}

void main()
{{
    ivec2 pix = ivec2(gl_FragCoord.xy);
    vec2 s = texelFetch(depth_tex, pix, 0).rg;
    if (s.r <= 0.0)
        discard;
    int batch = int(s.g + 0.5);
    vec3 p = eye_position(v_uv, s.r);

    // normal from the smaller one-sided difference on each axis: no smearing across silhouettes
    bool ok_r, ok_l, ok_u, ok_d;
    vec3 pr = fetch_eye(pix + ivec2(1, 0), s.r, ok_r);
    vec3 pl = fetch_eye(pix - ivec2(1, 0), s.r, ok_l);
    vec3 pu = fetch_eye(pix + ivec2(0, 1), s.r, ok_u);
    vec3 pd = fetch_eye(pix - ivec2(0, 1), s.r, ok_d);
    vec3 dx = (!ok_l || (ok_r && abs(pr.z - p.z) < abs(p.z - pl.z))) ? pr - p : p - pl;
    vec3 dy = (!ok_d || (ok_u && abs(pu.z - p.z) < abs(p.z - pd.z))) ? pu - p : p - pd;
    vec3 n = normalize(cross(dx, dy));
    vec3 v = normalize(-p);
    if (dot(n, v) < 0.0)
        n = -n;

    vec4 optical = texture(optical_tex, v_uv);
    vec3 transmission = exp(-optical.rgb);

    // refraction: shift the lookup of the scene behind along the normal, more for thicker fluid
    float bend = (1.0 - 1.0 / ior[batch]) * min(optical.a, 0.1);
    vec2 uv_behind = clamp(v_uv + n.xy * bend * projection[1][1] / max(s.r, 1.0e-3), vec2(0.0), vec2(1.0));
    vec4 clip = projection * vec4(p, 1.0);
    float surface_depth = clip.z / clip.w * 0.5 + 0.5;
    // what lies in front of the fluid cannot be seen through it
    if (texture(scene_depth_tex, uv_behind).r < surface_depth)
        uv_behind = v_uv;
    vec3 behind = pow(texture(scene_tex, uv_behind).rgb, vec3(2.2));

    float cos_v = clamp(dot(n, v), 0.0, 1.0);
    float f0 = reflectance[batch];
    float fresnel = f0 + (1.0 - f0) * pow(1.0 - cos_v, 5.0);

    mat3 eye_to_world = transpose(mat3(view));
    vec3 r_world = eye_to_world * reflect(-v, n);
    vec3 reflected = environment(r_world);

    float shadow = in_shadow(eye_to_world * p);
    vec3 h = normalize(sun_dir_eye + v);
    float spec = specular_intensity[batch] * pow(max(dot(n, h), 0.0), specular_power[batch]);
    spec *= step(0.0, dot(n, sun_dir_eye)) * (1.0 - shadow);

    vec3 tint = pow(base_color[batch].rgb, vec3(2.2));
    vec3 refracted = behind * transmission;
    // light the fluid itself scatters back: what is not transmitted, in the batch colour
    vec3 scattered = tint * (1.0 - transmission) * base_color[batch].a * (0.35 + 0.65 * (1.0 - 0.5 * shadow)) * 0.5;
    vec3 color = mix(refracted + scattered, reflected, fresnel) + vec3(spec);
    out_color = vec4(pow(clamp(color, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
    gl_FragDepth = surface_depth;
}}
"""

# Velocity-stretched sprite of one diffuse particle (spray, foam, bubble): a camera-facing quad
# elongated along the particle's screen-space motion. It is tested against the scene's depth in
# the shader (the frame's depth buffer holds the fluid surface by now) and fades with the depth
# of fluid in front of it, so bubbles show faintly through the surface.
DIFFUSE_VERTEX = """
#version 330 core
layout(location = 0) in vec2 corner;
layout(location = 1) in vec4 center_radius;
layout(location = 2) in vec4 velocity_kind;

uniform mat4 view;
uniform mat4 projection;
uniform float stretch_time;

out vec2 v_corner;
flat out float v_depth;
flat out float v_radius;
flat out float v_kind;

void main()
{
    float r = center_radius.w;
    if (r <= 0.0) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        return;
    }
    vec3 c = (view * vec4(center_radius.xyz, 1.0)).xyz;
    vec3 vel = mat3(view) * velocity_kind.xyz;
    float speed = length(vel.xy);
    vec2 along = speed > 1.0e-6 ? vel.xy / speed : vec2(1.0, 0.0);
    vec2 across = vec2(-along.y, along.x);
    float half_length = r + 0.5 * speed * stretch_time;
    vec3 p = c + vec3(corner.x * half_length * along + corner.y * r * across, 0.0);
    v_corner = corner;
    v_depth = -c.z;
    v_radius = r;
    v_kind = velocity_kind.w;
    gl_Position = projection * vec4(p, 1.0);
}
"""

DIFFUSE_FRAGMENT = """
#version 330 core
in vec2 v_corner;
flat in float v_depth;
flat in float v_radius;
flat in float v_kind;

uniform sampler2D fluid_depth_tex;
uniform sampler2D scene_depth_tex;
uniform mat4 projection;
uniform vec4 color;
uniform float fade_length;
layout(location = 0) out vec4 out_color;

void main()
{
    float d2 = dot(v_corner, v_corner);
    if (d2 > 1.0)
        discard;
    ivec2 pix = ivec2(gl_FragCoord.xy);
    vec4 clip = projection * vec4(0.0, 0.0, -v_depth, 1.0);
    if (texelFetch(scene_depth_tex, pix, 0).r < clip.z / clip.w * 0.5 + 0.5)
        discard;
    float alpha = color.a * (1.0 - d2);
    float fluid = texelFetch(fluid_depth_tex, pix, 0).r;
    if (fluid > 0.0 && v_depth > fluid + v_radius)
        alpha *= exp(-(v_depth - fluid) / fade_length);
    // bubbles are darker rims, spray and foam are white
    vec3 rgb = v_kind > 1.5 ? color.rgb * 0.8 : color.rgb;
    out_color = vec4(rgb * alpha, alpha);
}
"""
