// The wavefront's path state and its shading stage in scalars (kernels/wavefront.cl launches
// them; docs/wavefront.md). Every function repeats, operation for operation, the arithmetic of the
// path piece it names (path/primal.h, two_state.h, interaction.h, emission.h, nee.h,
// continuation.h; shared/textures.h, sampling.h), with selects where those branch, so that the
// images are the megakernels' bits and PoCL's loop vectoriser can run 8 paths per instruction.
#ifndef TANDEM_KERNELS_PATH_WAVEFRONT_H
#define TANDEM_KERNELS_PATH_WAVEFRONT_H

#include "path/wavefront_lookup.h"
#include "shared/wavefront_layout.h"

#if HAS_DELTA_LIGHTS || LIGHT_STRATEGY != STRATEGY_MIS
#error "the wavefront renders scenes lit by area and environment lights with MIS only (wavefront_supported)"
#endif
/// Materials other than diffuse are shaded by a stage of their own (kernels/wavefront.cl:
/// wf_shade_general), not vectorised; so is every primary vertex of a RESTIR=1 build that reads
/// its light sample from a reservoir (path/restir.h).
#define WF_GENERAL (BSDF_CONDUCTOR || BSDF_DIELECTRIC || BSDF_PLASTIC || RESTIR)

// Path flags.
#define WF_ALIVE 1u  // the path continues: its ray is to be traced
#define WF_SHADOW 2u // a light sample waits for its shadow ray
// the replay's: derivatives that wait for wf_replay_shadow
#define WF_EMITTED 4u    // of the emission found (WF_GRAD_EMIT), whose radiance is a parameter
#define WF_SHADED 8u     // of the vertex's albedo: its light sample's, its continuation's
#define WF_CONTINUED 16u // the continuation's (WF_CONT_F, WF_CONT_G)
// Modes of the shading stage (wf_shade_path).
#define WF_MODE_PRIMAL 0
#define WF_MODE_TWO_STATE 1
#define WF_MODE_REPLAY 2

#define WF_F(field) state[(field) * n + i]
#define WF_U(field) ustate[(field) * n + i]
/// Fields field, field + 1 and field + 2 (an rgb or a vector) of path i set to a, b, c.
#define WF_SET3(field, a, b, c)                                                                    \
    do {                                                                                           \
        WF_F(field) = (a);                                                                         \
        WF_F((field) + 1u) = (b);                                                                  \
        WF_F((field) + 2u) = (c);                                                                  \
    } while (0)


#if WF_GENERAL
/// Whether a path's ray of bounce `depth` found (primitive `prim`) a surface that wf_shade_path
/// does not shade: one of a material other than diffuse, or with RESTIR a primary vertex whose
/// slot the resampling pass served (`served`: its reservoir has a shading point; the others take
/// NEE's own sample, which wf_shade_path computes). wf_shade_general shades those paths, and
/// wf_shade_path leaves them alone.
TANDEM_INLINE int wf_general_hit(__global const TriangleInfo* infos,
                                 __global const Material* materials, uint prim, uint depth,
                                 int served) {
    return prim != HIT_NONE && ((RESTIR && depth == 0u && served) ||
                                materials[infos[prim].material].type != MATERIAL_DIFFUSE);
}
#endif

/// Stage 3, every bounce (`depth`), for path i: the surface its ray found (path_primal steps 2-6:
/// emission, NEE, BSDF sampling, Russian roulette), in scalars. A light sample with a non-zero
/// term leaves its shadow ray and term for wf_shadow. `mode` is a constant (each kernel keeps only
/// its own branches): WF_MODE_PRIMAL, path_primal; WF_MODE_TWO_STATE, path_two_state's, the same
/// path also estimating `params_old`; WF_MODE_REPLAY, path_replay's, with WF_L holding L_rem: the
/// terms found are subtracted, and their derivatives (path/adjoint.h) are left in the state for
/// wf_replay_shadow, which knows whether the light sample counts. A path whose surface is not
/// diffuse, or a primary vertex `served` by a reservoir, is left to wf_shade_general
/// (wf_general_hit).
TANDEM_INLINE void wf_shade_path(SCENE_ARGS RenderParams rp, __global const float* params,
                                 __global const float* params_old, const int mode,
                                 __global float* state, __global uint* ustate, uint n, uint depth,
                                 uint i, int served) {
    const int two_state = mode == WF_MODE_TWO_STATE, replay = mode == WF_MODE_REPLAY;
    const uint prim = WF_U(WF_PRIM);
    (void)served; // read by wf_general_hit only
#if WF_GENERAL
    if (wf_general_hit(infos, materials, prim, depth, served)) return; // wf_shade_general's
#endif
    const PathRng rng = path_rng(rp.seed, i, rp.sample_begin);
    const uint dim = path_dim(depth);
    const float bx = WF_F(WF_BETA), by = WF_F(WF_BETA + 1u), bz = WF_F(WF_BETA + 2u);
    float Lx = WF_F(WF_L), Ly = WF_F(WF_L + 1u), Lz = WF_F(WF_L + 2u);
    const float box = two_state ? WF_F(WF_BETA_OLD) : 0.0f,
                boy = two_state ? WF_F(WF_BETA_OLD + 1u) : 0.0f,
                boz = two_state ? WF_F(WF_BETA_OLD + 2u) : 0.0f;
    float Lox = two_state ? WF_F(WF_L_OLD) : 0.0f, Loy = two_state ? WF_F(WF_L_OLD + 1u) : 0.0f,
          Loz = two_state ? WF_F(WF_L_OLD + 2u) : 0.0f;
    // an escaped path ends, after the environment's emission
    int alive = prim != HIT_NONE;
    const uint p = alive ? prim : 0u; // a valid index for the loads of a path that ended
    const float u_choice = path_rand(rng, dim + DIM_LIGHT_CHOICE);
    const float u1 = path_rand(rng, dim + DIM_LIGHT_POINT);
    const float u2 = path_rand(rng, dim + DIM_LIGHT_POINT + 1u);
#if HAS_ENV_LIGHT
    // The environment, looked up once per vertex along the ray that escaped; where NEE chooses
    // the environment (nee_choose_light, nee_sample_env), its sample brings its own radiance and
    // density (envmap_sample_eval).
    const int env_light = u_choice < rp.light_env_prob;
    float env_dir[3], env_Le[3];
#if HAS_ENVMAP
    float sample_Le[3];
    const float sample_pdf =
        wf_envmap_sample(&envmap, env_texels, env_cdf, u1, u2, env_dir, sample_Le);
#else
    { // sample_uniform_sphere
        const float sz = 1.0f - 2.0f * u1;
        const float sr = sqrt(fmax(0.0f, 1.0f - sz * sz));
        float ss, sc;
        det_sincos(2.0f * TANDEM_PI * u2, &ss, &sc);
        env_dir[0] = sr * sc;
        env_dir[1] = sr * ss;
        env_dir[2] = sz;
    }
#endif
#if HAS_ENVMAP
    // the lookup along the ray serves a path that escaped; one still alive takes its sample's own
    float lookup_Le[3];
    const float lookup_pdf = wf_envmap_lookup(&envmap, env_texels, WF_F(WF_DX), WF_F(WF_DX + 1u),
                                              WF_F(WF_DX + 2u), lookup_Le);
    const float env_pdf = alive ? sample_pdf : lookup_pdf;
    env_Le[0] = alive ? sample_Le[0] : lookup_Le[0];
    env_Le[1] = alive ? sample_Le[1] : lookup_Le[1];
    env_Le[2] = alive ? sample_Le[2] : lookup_Le[2];
    const uint env_param = NO_PARAM; // an environment map is not a parameter
#else
    const float env_pdf = PDF_UNIFORM_SPHERE;
    const uint env_param = rp.env_param;
    env_Le[0] = wf_env_constant(params, env_param, 0u);
    env_Le[1] = wf_env_constant(params, env_param, 1u);
    env_Le[2] = wf_env_constant(params, env_param, 2u);
#endif
#endif

    // interaction_at: position, geometric normal, wi
    const float u = WF_F(WF_HIT_U), v = WF_F(WF_HIT_V), b0 = 1.0f - u - v;
    float hit_point[3], n_front[3];
#if BVH_ANALYTIC
    wf_primitive_point((__global const float*)(prims + p), u, v, hit_point, n_front);
    (void)b0;
#else
    wf_triangle_point((__global const float*)(prims + p), b0, u, v, hit_point, n_front);
#endif
    const float x = hit_point[0], y = hit_point[1], z = hit_point[2];
    const float nfx = n_front[0], nfy = n_front[1], nfz = n_front[2];
    const float wix = -WF_F(WF_DX), wiy = -WF_F(WF_DX + 1u), wiz = -WF_F(WF_DX + 2u);
    const uint material = infos[p].material, emitter = infos[p].emitter;

    // emission_area: an area light's front side; emission_env: the environment of a ray that
    // escaped; MIS-weighted after a BSDF sample
    const float cos_front = wix * nfx + wiy * nfy + wiz * nfz;
    const float tri_scale = 1.0f - rp.light_env_prob;
    const float prev_pdf = WF_F(WF_PREV_PDF);
#if HAS_AREA_LIGHTS
    const int emits_area = alive && emitter != NO_EMITTER && cos_front > 0.0f;
    const uint ei = emits_area ? emitter : 0u;
    __global const float* e = (__global const float*)(emissive + ei);
    const uint area_param = emissive[ei].radiance_param;
    const float t = WF_F(WF_HIT_T);
    const float pdf_area = wf_light_pdf_triangle(e, tri_scale, t * t, cos_front);
    const uint le = emits_area ? area_param : 0u;
    const float area_Lx = params[le], area_Ly = params[le + 1u], area_Lz = params[le + 2u];
#else
    const int emits_area = 0;
    const uint area_param = NO_PARAM, le = 0u;
    const float pdf_area = 0.0f, area_Lx = 0.0f, area_Ly = 0.0f, area_Lz = 0.0f;
#endif
#if HAS_ENV_LIGHT
    const int emits = emits_area || prim == HIT_NONE;
    const float pdf_emit = emits_area ? pdf_area : rp.light_env_prob * env_pdf;
    const uint e_param = emits_area ? area_param : env_param;
    const float Lex = emits_area ? area_Lx : env_Le[0], Ley = emits_area ? area_Ly : env_Le[1],
                Lez = emits_area ? area_Lz : env_Le[2];
#else
    const int emits = emits_area;
    const float pdf_emit = pdf_area;
    const uint e_param = area_param;
    const float Lex = area_Lx, Ley = area_Ly, Lez = area_Lz;
#endif
#if RESTIR // emission_mis_weight after a primary vertex whose reservoir took all direct light
    const float w_emit = depth == 0u || prev_pdf == INFINITY  ? 1.0f
                         : prev_pdf == EMISSION_AFTER_NEE_ALL ? (pdf_emit > 0.0f ? 0.0f : 1.0f)
                                                              : wf_mis_power(prev_pdf, pdf_emit);
#else
    const float w_emit =
        depth == 0u || prev_pdf == INFINITY ? 1.0f : wf_mis_power(prev_pdf, pdf_emit);
#endif
    if (replay) { // adjoint_emission, then the term leaves L_rem
        const float dx = WF_F(WF_DELTA), dy = WF_F(WF_DELTA + 1u), dz = WF_F(WF_DELTA + 2u);
        WF_SET3(WF_GRAD_EMIT, dx * bx * w_emit, dy * by * w_emit, dz * bz * w_emit);
        WF_U(WF_EMIT_PARAM) = e_param;
        Lx = emits ? Lx - bx * Lex * w_emit : Lx;
        Ly = emits ? Ly - by * Ley * w_emit : Ly;
        Lz = emits ? Lz - bz * Lez * w_emit : Lz;
    } else {
        Lx = emits ? Lx + bx * Lex * w_emit : Lx;
        Ly = emits ? Ly + by * Ley * w_emit : Ly;
        Lz = emits ? Lz + bz * Lez * w_emit : Lz;
    }
    if (two_state) { // emission_Le_in: the old state's radiance, the new state's weight
#if HAS_ENV_LIGHT && HAS_ENVMAP
        const float Lox_e = emits_area ? params_old[le] : Lex,
                    Loy_e = emits_area ? params_old[le + 1u] : Ley,
                    Loz_e = emits_area ? params_old[le + 2u] : Lez;
#elif HAS_ENV_LIGHT
        const float Lox_e = emits_area ? params_old[le] : wf_env_constant(params_old, env_param, 0u),
                    Loy_e = emits_area ? params_old[le + 1u] : wf_env_constant(params_old, env_param, 1u),
                    Loz_e = emits_area ? params_old[le + 2u] : wf_env_constant(params_old, env_param, 2u);
#else
        const float Lox_e = params_old[le], Loy_e = params_old[le + 1u], Loz_e = params_old[le + 2u];
#endif
        Lox = emits ? Lox + box * Lox_e * w_emit : Lox;
        Loy = emits ? Loy + boy * Loy_e * w_emit : Loy;
        Loz = emits ? Loz + boz * Loz_e * w_emit : Loz;
    }
    alive = alive && depth + 1u < rp.max_depth;

    // interaction_shade: the material (diffuse), the side seen, frame, albedo, ray origin
    const uint mi = alive ? material : 0u;
    const uint rparam = materials[mi].reflectance_param, mflags = materials[mi].flags;
    __global const float* mref = (__global const float*)(materials + mi);
    float ax = rparam != NO_PARAM ? params[rparam] : mref[0];
    float ay = rparam != NO_PARAM ? params[rparam + 1u] : mref[1];
    float az = rparam != NO_PARAM ? params[rparam + 2u] : mref[2];
    // the previous state's material at the same point (material_load, material_albedo)
    float aox = 0.0f, aoy = 0.0f, aoz = 0.0f;
    if (two_state) {
        aox = rparam != NO_PARAM ? params_old[rparam] : mref[0];
        aoy = rparam != NO_PARAM ? params_old[rparam + 1u] : mref[1];
        aoz = rparam != NO_PARAM ? params_old[rparam + 2u] : mref[2];
    }
#if HAS_TEXTURES
    // material_albedo: texture coordinates (interaction_shade: primitive_uv), the texture
    const uint texture = materials[mi].texture;
    const int textured = texture != NO_TEXTURE;
    const uint ti = textured ? texture : 0u;
    __global const float* uv = (__global const float*)(uvs + p);
#if BVH_ANALYTIC
    float tu, tv;
    wf_primitive_uv((__global const float*)(prims + p), uv, u, v, &tu, &tv);
#else
    const float tu = uv[0] * b0 + uv[2] * u + uv[4] * v;
    const float tv = uv[1] * b0 + uv[3] * u + uv[5] * v;
#endif
    if (textured) { // masked: untextured lanes gather nothing
        ax = wf_texture(textures, texels, params, ti, tu, tv, 0u);
        ay = wf_texture(textures, texels, params, ti, tu, tv, 1u);
        az = wf_texture(textures, texels, params, ti, tu, tv, 2u);
        if (two_state) {
            aox = wf_texture(textures, texels, params_old, ti, tu, tv, 0u);
            aoy = wf_texture(textures, texels, params_old, ti, tu, tv, 1u);
            aoz = wf_texture(textures, texels, params_old, ti, tu, tv, 2u);
        }
    }
#endif
    alive = alive && !(mflags & MATERIAL_FLAG_BLACK);
    const int flip = (mflags & MATERIAL_FLAG_TWOSIDED) && cos_front < 0.0f;
    const float nx = flip ? -nfx : nfx, ny = flip ? -nfy : nfy, nz = flip ? -nfz : nfz;
    const float cos_n = wix * nx + wiy * ny + wiz * nz;
    alive = alive && !(cos_n <= 0.0f);
    const int shaded = alive; // path_replay pushes this vertex's albedo derivatives
    // frame_from_normal
    const float sign = nz >= 0.0f ? 1.0f : -1.0f;
    const float fa = -1.0f / (sign + nz);
    const float fb = nx * ny * fa;
    const float sx = 1.0f + sign * nx * nx * fa, sy = sign * fb, sz = -sign * nx;
    const float tx = fb, ty = sign + ny * ny * fa, tz = -ny;
    const float wi_lx = wix * sx + wiy * sy + wiz * sz, wi_ly = wix * tx + wiy * ty + wiz * tz;
    const float wi_lz = wix * nx + wiy * ny + wiz * nz;
    (void)wi_lx;
    (void)wi_ly;
    const float ox_n = cos_n >= 0.0f ? nx : -nx, oy_n = cos_n >= 0.0f ? ny : -ny,
                oz_n = cos_n >= 0.0f ? nz : -nz; // n_out
    const float orx = offset_component(x, ox_n), ory = offset_component(y, oy_n),
                orz = offset_component(z, oz_n);

    // NEE (path_nee_term: nee_choose_light, nee_sample_triangle or nee_sample_env, nee_eval,
    // nee_weight): the light sample's direction wo, radiance lL (lLo: the old state's), parameter,
    // density, and shadow ray
    float wox, woy, woz, lLx, lLy, lLz, lLox, lLoy, lLoz, pdf_light, sdx, sdy, sdz, stmax;
    uint lparam;
#if HAS_AREA_LIGHTS
    // the alias table (a lane that chose the environment decodes slot 0, unused)
#if HAS_ENV_LIGHT
    const float uc = env_light ? 0.0f : (u_choice - rp.light_env_prob) / (1.0f - rp.light_env_prob);
#else
    const float uc = (u_choice - rp.light_env_prob) / (1.0f - rp.light_env_prob);
#endif
    const float u_alias = path_rand(rng, dim + DIM_ALIAS);
    const uint count = rp.emissive_count + rp.delta_count;
    const uint slot0 = min((uint)(uc * (float)count), count - 1u);
    const uint light = u_alias >= alias[slot0].q ? alias[slot0].alias : slot0;
    __global const float* q = (__global const float*)(emissive + light);
    const float su = sqrt(u1);
    const float lb0 = 1.0f - su, lb1 = u2 * su, lb2 = 1.0f - lb0 - lb1;
    float light_point[3], n_light[3];
    wf_triangle_point(q, lb0, lb1, lb2, light_point, n_light);
    const float lyx = light_point[0], lyy = light_point[1], lyz = light_point[2];
    const float nlx = n_light[0], nly = n_light[1], nlz = n_light[2];
    const float tlx = lyx - orx, tly = lyy - ory, tlz = lyz - orz;
    const float dist2 = tlx * tlx + tly * tly + tlz * tlz;
    const float inv_dist = 1.0f / sqrt(dist2);
    wox = tlx * inv_dist;
    woy = tly * inv_dist;
    woz = tlz * inv_dist;
    lparam = emissive[light].radiance_param;
    lLx = params[lparam];
    lLy = params[lparam + 1u];
    lLz = params[lparam + 2u];
    lLox = two_state ? params_old[lparam] : 0.0f;
    lLoy = two_state ? params_old[lparam + 1u] : 0.0f;
    lLoz = two_state ? params_old[lparam + 2u] : 0.0f;
    const float cos_light = -(wox * nlx + woy * nly + woz * nlz);
    pdf_light = wf_light_pdf_triangle(q, tri_scale, dist2, cos_light);
    const int behind = nlx * wox + nly * woy + nlz * woz < 0.0f; // the light's side facing us
    const float snx = behind ? nlx : -nlx, sny = behind ? nly : -nly, snz = behind ? nlz : -nlz;
    sdx = offset_component(lyx, snx) - orx;
    sdy = offset_component(lyy, sny) - ory;
    sdz = offset_component(lyz, snz) - orz;
    stmax = 1.0f;
#else
    // no triangle to sample: a lane that does not choose the environment has no sample
    wox = woy = woz = lLx = lLy = lLz = lLox = lLoy = lLoz = pdf_light = sdx = sdy = sdz = 0.0f;
    stmax = 0.0f;
    lparam = NO_PARAM;
#endif
#if HAS_ENV_LIGHT
    // nee_sample_env: the sample's own radiance and density; the shadow ray goes to infinity
    wox = env_light ? env_dir[0] : wox;
    woy = env_light ? env_dir[1] : woy;
    woz = env_light ? env_dir[2] : woz;
    lLx = env_light ? env_Le[0] : lLx;
    lLy = env_light ? env_Le[1] : lLy;
    lLz = env_light ? env_Le[2] : lLz;
#if HAS_ENVMAP
    lLox = env_light ? env_Le[0] : lLox;
    lLoy = env_light ? env_Le[1] : lLoy;
    lLoz = env_light ? env_Le[2] : lLoz;
#else
    if (two_state) {
        lLox = env_light ? wf_env_constant(params_old, env_param, 0u) : lLox;
        lLoy = env_light ? wf_env_constant(params_old, env_param, 1u) : lLoy;
        lLoz = env_light ? wf_env_constant(params_old, env_param, 2u) : lLoz;
    }
#endif
    lparam = env_light ? env_param : lparam;
    pdf_light = env_light ? rp.light_env_prob * env_pdf : pdf_light;
    sdx = env_light ? env_dir[0] : sdx;
    sdy = env_light ? env_dir[1] : sdy;
    sdz = env_light ? env_dir[2] : sdz;
    stmax = env_light ? INFINITY : stmax;
#endif
    // nee_eval: wo in the frame, diffuse f (bsdf_diffuse_eval)
    const float wo_lx = wox * sx + woy * sy + woz * sz, wo_ly = wox * tx + woy * ty + woz * tz;
    const float wo_lz = wox * nx + woy * ny + woz * nz;
    (void)wo_lx;
    (void)wo_ly;
    const int lit = !(wi_lz <= 0.0f || wo_lz <= 0.0f);
    const float cos_pi = TANDEM_INV_PI * wo_lz;
    const float fx = lit ? ax * cos_pi : 0.0f, fy = lit ? ay * cos_pi : 0.0f,
                fz = lit ? az * cos_pi : 0.0f;
    // the old state's f toward the same light
    const float fox = lit ? aox * cos_pi : 0.0f, foy = lit ? aoy * cos_pi : 0.0f,
                foz = lit ? aoz * cos_pi : 0.0f;
    const int shadow = alive && pdf_light > 0.0f &&
                       (fmax(fx, fmax(fy, fz)) > 0.0f || (two_state && fmax(fox, fmax(foy, foz)) > 0.0f));
    const float pdf_bsdf = wi_lz <= 0.0f ? 0.0f : fmax(wo_lz, 0.0f) * TANDEM_INV_PI;
    const float w_nee = wf_mis_power(pdf_light, pdf_bsdf) / pdf_light;
    if (shadow) {
        WF_SET3(WF_SHADOW_O, orx, ory, orz);
        WF_SET3(WF_SHADOW_D, sdx, sdy, sdz);
        WF_F(WF_SHADOW_TMAX) = stmax;
        WF_SET3(WF_CONTRIB, bx * fx * lLx * w_nee, by * fy * lLy * w_nee, bz * fz * lLz * w_nee);
        if (two_state) { // nee_Le_in: the old state's radiance, the new state's weight
            WF_SET3(WF_CONTRIB_OLD, box * fox * lLox * w_nee, boy * foy * lLoy * w_nee,
                    boz * foz * lLoz * w_nee);
        }
        if (replay) { // adjoint_nee: k = delta beta Le w times d f / d albedo (lit: cos / pi)
            const float dx = WF_F(WF_DELTA), dy = WF_F(WF_DELTA + 1u), dz = WF_F(WF_DELTA + 2u);
            WF_SET3(WF_GRAD_NEE, dx * bx * lLx * w_nee * cos_pi, dy * by * lLy * w_nee * cos_pi,
                    dz * bz * lLz * w_nee * cos_pi);
            WF_SET3(WF_GRAD_LIGHT, dx * bx * fx * w_nee, dy * by * fy * w_nee, dz * bz * fz * w_nee);
            WF_U(WF_LIGHT_PARAM) = lparam;
        }
    }

    // continuation_sample: a cosine-weighted direction (sample_concentric_disk, with selects)
    const float v1 = path_rand(rng, dim + DIM_BSDF), v2 = path_rand(rng, dim + DIM_BSDF + 1u);
    const float dxs = 2.0f * v1 - 1.0f, dys = 2.0f * v2 - 1.0f;
    const int wide = fabs(dxs) > fabs(dys);
    const float r = wide ? dxs : dys;
    float sin_q, cos_q;
    det_sincos_quarter_pi(wide ? dys / dxs : dxs / dys, &sin_q, &cos_q);
    const int origin_disk = dxs == 0.0f && dys == 0.0f;
    const float dkx = origin_disk ? 0.0f : r * (wide ? cos_q : sin_q);
    const float dky = origin_disk ? 0.0f : r * (wide ? sin_q : cos_q);
    const float dkz = sqrt(fmax(0.0f, 1.0f - dkx * dkx - dky * dky));
    const float pdf = fmax(dkz, 0.0f) * TANDEM_INV_PI;
    // bsdf_diffuse_sample's weight is the albedo where it succeeds (continuation_failed)
    alive = alive && !(wi_lz <= 0.0f || pdf <= 0.0f);
    // continuation_weight_old: f_old / p as weight * (f_old / f_new) where f_new > 0
    float wox_c = 0.0f, woy_c = 0.0f, woz_c = 0.0f;
    if (two_state) {
        const int lit_c = !(wi_lz <= 0.0f || dkz <= 0.0f);
        const float cos_c = TANDEM_INV_PI * dkz, inv_pdf = 1.0f / pdf;
        const float fnx = lit_c ? ax * cos_c : 0.0f, fny = lit_c ? ay * cos_c : 0.0f,
                    fnz = lit_c ? az * cos_c : 0.0f;
        const float fcx = lit_c ? aox * cos_c : 0.0f, fcy = lit_c ? aoy * cos_c : 0.0f,
                    fcz = lit_c ? aoz * cos_c : 0.0f;
        const float rx = ax * (fnx != 0.0f ? fcx / fnx : 0.0f),
                    ry = ay * (fny != 0.0f ? fcy / fny : 0.0f),
                    rz = az * (fnz != 0.0f ? fcz / fnz : 0.0f);
        wox_c = fnx > 0.0f && wf_finite(rx) ? rx : fcx * inv_pdf;
        woy_c = fny > 0.0f && wf_finite(ry) ? ry : fcy * inv_pdf;
        woz_c = fnz > 0.0f && wf_finite(rz) ? rz : fcz * inv_pdf;
        alive = alive && !(fmax(ax, fmax(ay, az)) <= 0.0f && fmax(wox_c, fmax(woy_c, woz_c)) <= 0.0f);
    } else {
        alive = alive && !(fmax(ax, fmax(ay, az)) <= 0.0f);
    }
    if (replay && alive) { // adjoint_continuation's f and d f / d albedo (bsdf_diffuse_eval)
        const int lit_c = !(wi_lz <= 0.0f || dkz <= 0.0f);
        const float cos_c = TANDEM_INV_PI * dkz;
        WF_SET3(WF_CONT_F, lit_c ? ax * cos_c : 0.0f, lit_c ? ay * cos_c : 0.0f,
                lit_c ? az * cos_c : 0.0f);
        WF_F(WF_CONT_G) = lit_c ? cos_c : 0.0f;
    }
    const int continued = alive;
    float nbx = bx * ax, nby = by * ay, nbz = bz * az;
    float nbox = box * wox_c, nboy = boy * woy_c, nboz = boz * woz_c;
    // continuation_ray
    const float rdx = sx * dkx + tx * dky + nx * dkz, rdy = sy * dkx + ty * dky + ny * dkz,
                rdz = sz * dkx + tz * dky + nz * dkz;
    const int same_side = rdx * ox_n + rdy * oy_n + rdz * oz_n >= 0.0f;
    const float rox = same_side ? orx : offset_component(x, -ox_n);
    const float roy = same_side ? ory : offset_component(y, -oy_n);
    const float roz = same_side ? orz : offset_component(z, -oz_n);
    // Russian roulette (roulette_q, roulette_ends)
    const int roulette = depth + 1u >= rp.rr_depth;
    // (roulette_q_two_state: on the componentwise max of |beta| and |beta_old|)
    const float q_rr =
        two_state ? fmin(fmax(fmax(fabs(nbx), fabs(nbox)),
                              fmax(fmax(fabs(nby), fabs(nboy)), fmax(fabs(nbz), fabs(nboz)))),
                         0.95f)
                  : fmin(fmax(nbx, fmax(nby, nbz)), 0.95f);
    const float u_rr = path_rand(rng, dim + DIM_RR);
    alive = alive && !(roulette && u_rr >= q_rr);
    const float inv_q = 1.0f / q_rr;
    nbx = roulette ? nbx * inv_q : nbx;
    nby = roulette ? nby * inv_q : nby;
    nbz = roulette ? nbz * inv_q : nbz;
    nbox = roulette ? nbox * inv_q : nbox;
    nboy = roulette ? nboy * inv_q : nboy;
    nboz = roulette ? nboz * inv_q : nboz;
    if (alive && two_state) {
        WF_SET3(WF_BETA_OLD, nbox, nboy, nboz);
    }
    if (alive) {
        WF_SET3(WF_OX, rox, roy, roz);
        WF_SET3(WF_DX, rdx, rdy, rdz);
        WF_F(WF_TMIN) = 0.0f;
        WF_F(WF_TMAX) = INFINITY;
        WF_SET3(WF_BETA, nbx, nby, nbz);
        WF_F(WF_PREV_PDF) = pdf;
    }
    WF_SET3(WF_L, Lx, Ly, Lz);
    if (two_state) {
        WF_SET3(WF_L_OLD, Lox, Loy, Loz);
    }
    if (replay && shaded) {
        WF_U(WF_MATERIAL) = mi;
#if HAS_TEXTURES
        WF_F(WF_TU) = tu;
        WF_F(WF_TV) = tv;
#endif
    }
    WF_U(WF_FLAGS) = (alive ? WF_ALIVE : 0u) | (shadow ? WF_SHADOW : 0u) |
                     (replay && emits && e_param != NO_PARAM ? WF_EMITTED : 0u) | (replay && shaded ? WF_SHADED : 0u) |
                     (replay && continued ? WF_CONTINUED : 0u);
}


#endif // TANDEM_KERNELS_PATH_WAVEFRONT_H
