// The wavefront's path state and its shading stage (kernels/wavefront.cl launches them;
// docs/wavefront.md, "One copy of each path step"). The stage holds no path arithmetic of its
// own: it loads a path's state, calls the pieces the megakernels call (path/emission.h, nee.h,
// interaction.h, continuation.h, adjoint.h; shared/bsdfs.h, sampling.h, textures.h, envmap.h) in
// their scalar forms, selects between their results where a megakernel branches, and stores the
// state back. So the images are the megakernels' bits, and PoCL's loop vectoriser can run the
// stage 8 paths per instruction (no float3, no call left after inlining, no inner loop).
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
#define WF_GENERAL (BSDF_CONDUCTOR || BSDF_DIELECTRIC || BSDF_PLASTIC || RESTIR || HAS_SHADING_NORMALS)

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
/// NEE's own sample, which wf_shade_path computes), or one shaded with vertex normals
/// (interaction_shade's interpolated_normal). wf_shade_general shades those paths, and
/// wf_shade_path leaves them alone.
TANDEM_INLINE int wf_general_hit(__global const TriangleInfo* infos,
                                 __global const Material* materials,
                                 __global const TriangleNormals* normals, uint prim, uint depth,
                                 int served) {
    (void)normals;
    return prim != HIT_NONE && ((RESTIR && depth == 0u && served) ||
                                (HAS_SHADING_NORMALS && normals[prim].link.x != 0u) ||
                                materials[infos[prim].material].type != MATERIAL_DIFFUSE);
}
#endif

/// Stage 3, every bounce (`depth`), for path i: the surface its ray found, path_primal's steps
/// 2-6 (emission, NEE, BSDF sampling, Russian roulette) for a diffuse surface or a ray that
/// escaped. It reads the path's state, calls the pieces the megakernels call (emission.h, nee.h,
/// continuation.h, adjoint.h; shared/bsdfs.h and sampling.h), one channel at a time, and writes
/// the state back. Where a megakernel branches, this stage computes both sides and selects, so
/// that it stays one block that PoCL's loop vectoriser can run 8 paths per instruction; the values
/// it keeps are the megakernels', so the images are their bits. A light sample with a non-zero
/// term leaves its shadow ray and term for wf_shadow. `mode` is a constant (each kernel keeps
/// only its own branches): WF_MODE_PRIMAL, path_primal_vertex; WF_MODE_TWO_STATE,
/// path_two_state_vertex, the same path also estimating `params_old`; WF_MODE_REPLAY,
/// path_replay_vertex, with WF_L holding L_rem: the terms found are subtracted, and their
/// derivatives' factors (adjoint.h) are left in the state for wf_replay_shadow, which knows
/// whether the light sample counts. A path whose surface is not diffuse, or a primary vertex
/// `served` by a reservoir, is left to wf_shade_general (wf_general_hit).
TANDEM_INLINE void wf_shade_path(SCENE_ARGS RenderParams rp, __global const float* params,
                                 __global const float* params_old, const int mode,
                                 __global float* state, __global uint* ustate, uint n, uint depth,
                                 uint i, int served) {
    const int two_state = mode == WF_MODE_TWO_STATE, replay = mode == WF_MODE_REPLAY;
    const uint prim = WF_U(WF_PRIM);
    (void)served; // read by wf_general_hit only
#if WF_GENERAL
    if (wf_general_hit(infos, materials, normals, prim, depth, served)) return; // wf_shade_general's
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
    const float dx = replay ? WF_F(WF_DELTA) : 0.0f, dy = replay ? WF_F(WF_DELTA + 1u) : 0.0f,
                dz = replay ? WF_F(WF_DELTA + 2u) : 0.0f;
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
        envmap_sample(&envmap, env_texels, env_cdf, u1, u2, env_dir, sample_Le);
    // the lookup along the ray serves a path that escaped; one still alive takes its sample's own
    float lookup_Le[3];
    const float lookup_pdf = envmap_lookup(&envmap, env_texels, WF_F(WF_DX), WF_F(WF_DX + 1u),
                                           WF_F(WF_DX + 2u), lookup_Le);
    const float env_pdf = alive ? sample_pdf : lookup_pdf;
    env_Le[0] = alive ? sample_Le[0] : lookup_Le[0];
    env_Le[1] = alive ? sample_Le[1] : lookup_Le[1];
    env_Le[2] = alive ? sample_Le[2] : lookup_Le[2];
    const uint env_param = NO_PARAM; // an environment map is not a parameter (light_env_param)
#else
    uniform_sphere(u1, u2, env_dir); // nee_sample_env
    const float env_pdf = PDF_UNIFORM_SPHERE;
    const uint env_param = rp.env_param;
    env_Le[0] = light_env_constant(params, env_param, 0u);
    env_Le[1] = light_env_constant(params, env_param, 1u);
    env_Le[2] = light_env_constant(params, env_param, 2u);
#endif
#endif

    // interaction_at: position, geometric normal, wi
    const float u = WF_F(WF_HIT_U), v = WF_F(WF_HIT_V);
    float hit_point[3], n_front[3];
#if BVH_ANALYTIC
    wf_primitive_point((__global const float*)(prims + p), u, v, hit_point, n_front);
#else
    triangle_hit_point((__global const float*)(prims + p), u, v, hit_point, n_front);
#endif
    const float x = hit_point[0], y = hit_point[1], z = hit_point[2];
    const float nfx = n_front[0], nfy = n_front[1], nfz = n_front[2];
    const float wix = -WF_F(WF_DX), wiy = -WF_F(WF_DX + 1u), wiz = -WF_F(WF_DX + 2u);
    const uint material = infos[p].material, emitter = infos[p].emitter;

    // emission_area: an area light's front side; emission_env: the environment of a ray that
    // escaped; MIS-weighted after a BSDF sample
    const float cos_front = dot3(wix, wiy, wiz, nfx, nfy, nfz);
#if HAS_AREA_LIGHTS
    const int emits_area = alive && emitter != NO_EMITTER && cos_front > 0.0f;
    const uint ei = emits_area ? emitter : 0u;
    __global const float* e = (__global const float*)(emissive + ei);
    const uint area_param = emissive[ei].radiance_param;
    const float pdf_area = emission_area_pdf(&rp, e[3], e[7], WF_F(WF_HIT_T), cos_front);
    const uint le = emits_area ? area_param : 0u;
    const float area_Lx = params[le], area_Ly = params[le + 1u], area_Lz = params[le + 2u];
#else
    const int emits_area = 0;
    const uint area_param = NO_PARAM, le = 0u;
    const float pdf_area = 0.0f, area_Lx = 0.0f, area_Ly = 0.0f, area_Lz = 0.0f;
#endif
#if HAS_ENV_LIGHT
    const int emits = emits_area || prim == HIT_NONE;
    const float pdf_emit = emits_area ? pdf_area : light_env_choice_pdf(&rp, env_pdf);
    const uint e_param = emits_area ? area_param : env_param;
    const float Lex = emits_area ? area_Lx : env_Le[0], Ley = emits_area ? area_Ly : env_Le[1],
                Lez = emits_area ? area_Lz : env_Le[2];
#else
    const int emits = emits_area;
    const float pdf_emit = pdf_area;
    const uint e_param = area_param;
    const float Lex = area_Lx, Ley = area_Ly, Lez = area_Lz;
#endif
    const float w_emit = emission_weight(depth, WF_F(WF_PREV_PDF), pdf_emit);
    if (replay) { // adjoint_emission, then the term leaves L_rem
        WF_SET3(WF_GRAD_EMIT, adjoint_emission_channel(dx, bx, w_emit),
                adjoint_emission_channel(dy, by, w_emit), adjoint_emission_channel(dz, bz, w_emit));
        WF_U(WF_EMIT_PARAM) = e_param;
        Lx = emits ? path_term_sub(Lx, bx, Lex, w_emit) : Lx;
        Ly = emits ? path_term_sub(Ly, by, Ley, w_emit) : Ly;
        Lz = emits ? path_term_sub(Lz, bz, Lez, w_emit) : Lz;
    } else {
        Lx = emits ? path_term_add(Lx, bx, Lex, w_emit) : Lx;
        Ly = emits ? path_term_add(Ly, by, Ley, w_emit) : Ly;
        Lz = emits ? path_term_add(Lz, bz, Lez, w_emit) : Lz;
    }
    if (two_state) { // emission_Le_in: the old state's radiance, the new state's weight
#if HAS_ENV_LIGHT && HAS_ENVMAP
        const float Lox_e = emits_area ? params_old[le] : Lex,
                    Loy_e = emits_area ? params_old[le + 1u] : Ley,
                    Loz_e = emits_area ? params_old[le + 2u] : Lez;
#elif HAS_ENV_LIGHT
        const float Lox_e = emits_area ? params_old[le] : light_env_constant(params_old, env_param, 0u),
                    Loy_e = emits_area ? params_old[le + 1u] : light_env_constant(params_old, env_param, 1u),
                    Loz_e = emits_area ? params_old[le + 2u] : light_env_constant(params_old, env_param, 2u);
#else
        const float Lox_e = params_old[le], Loy_e = params_old[le + 1u], Loz_e = params_old[le + 2u];
#endif
        Lox = emits ? path_term_add(Lox, box, Lox_e, w_emit) : Lox;
        Loy = emits ? path_term_add(Loy, boy, Loy_e, w_emit) : Loy;
        Loz = emits ? path_term_add(Loz, boz, Loz_e, w_emit) : Loz;
    }
    alive = alive && path_continues(&rp, depth);

    // interaction_shade: the material (diffuse), the side seen, frame, albedo, ray origin
    const uint mi = alive ? material : 0u;
    const uint rparam = materials[mi].reflectance_param, mflags = materials[mi].flags;
    __global const float* mref = (__global const float*)(materials + mi);
    float ax = param_or(params, rparam, 0u, mref[0]);
    float ay = param_or(params, rparam, 1u, mref[1]);
    float az = param_or(params, rparam, 2u, mref[2]);
    // the previous state's material at the same point (material_load, material_albedo)
    float aox = 0.0f, aoy = 0.0f, aoz = 0.0f;
    if (two_state) {
        aox = param_or(params_old, rparam, 0u, mref[0]);
        aoy = param_or(params_old, rparam, 1u, mref[1]);
        aoz = param_or(params_old, rparam, 2u, mref[2]);
    }
#if HAS_TEXTURES
    // material_albedo: texture coordinates (interaction_shade: primitive_uv), the texture
    const uint texture = materials[mi].texture;
    const int textured = texture != NO_TEXTURE;
    const uint ti = textured ? texture : 0u;
    __global const float* uv = (__global const float*)(uvs + p);
    float tu, tv;
#if BVH_ANALYTIC
    wf_primitive_uv((__global const float*)(prims + p), uv, u, v, &tu, &tv);
#else
    triangle_uv(uv, u, v, &tu, &tv);
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
    const int flip = interaction_flips(mflags, cos_front);
    const float nx = flip ? -nfx : nfx, ny = flip ? -nfy : nfy, nz = flip ? -nfz : nfz;
    const float cos_n = dot3(wix, wiy, wiz, nx, ny, nz);
    alive = alive && !(cos_n <= 0.0f);
    const int shaded = alive; // path_replay pushes this vertex's albedo derivatives
    float fs[3], ft[3]; // frame_from_normal: the tangents
    frame_tangents(nx, ny, nz, fs, ft);
    const float wi_lz = cos_n; // frame_to_local's z
    const float ox_n = cos_n >= 0.0f ? nx : -nx, oy_n = cos_n >= 0.0f ? ny : -ny,
                oz_n = cos_n >= 0.0f ? nz : -nz; // n_out
    const float origin[3] = {offset_component(x, ox_n), offset_component(y, oy_n),
                             offset_component(z, oz_n)};

    // NEE (path_nee_term: nee_choose_light, nee_sample_triangle or nee_sample_env, nee_eval,
    // nee_weight): the light sample's direction wo, radiance lL (lLo: the old state's), parameter,
    // density, and shadow ray
    float wo[3], sd[3], lLx, lLy, lLz, lLox, lLoy, lLoz, pdf_light, stmax;
    uint lparam;
#if HAS_AREA_LIGHTS
    // the alias table (a lane that chose the environment decodes slot 0, unused)
#if HAS_ENV_LIGHT
    const float uc = env_light ? 0.0f : nee_alias_choice(&rp, u_choice);
#else
    const float uc = nee_alias_choice(&rp, u_choice);
#endif
    const uint light = nee_alias_pick(alias, rp.emissive_count + rp.delta_count, uc,
                                      path_rand(rng, dim + DIM_ALIAS));
    float dist2, cos_light;
    pdf_light = nee_triangle_sample((__global const float*)(emissive + light), origin,
                                    light_alias_prob(&rp), u1, u2, wo, &dist2, &cos_light, sd);
    lparam = emissive[light].radiance_param;
    lLx = params[lparam];
    lLy = params[lparam + 1u];
    lLz = params[lparam + 2u];
    lLox = two_state ? params_old[lparam] : 0.0f;
    lLoy = two_state ? params_old[lparam + 1u] : 0.0f;
    lLoz = two_state ? params_old[lparam + 2u] : 0.0f;
    stmax = 1.0f;
#else
    // no triangle to sample: a lane that does not choose the environment has no sample
    wo[0] = wo[1] = wo[2] = sd[0] = sd[1] = sd[2] = 0.0f;
    lLx = lLy = lLz = lLox = lLoy = lLoz = pdf_light = stmax = 0.0f;
    lparam = NO_PARAM;
#endif
#if HAS_ENV_LIGHT
    // nee_sample_env: the sample's own radiance and density; the shadow ray goes to infinity
    wo[0] = env_light ? env_dir[0] : wo[0];
    wo[1] = env_light ? env_dir[1] : wo[1];
    wo[2] = env_light ? env_dir[2] : wo[2];
    sd[0] = env_light ? env_dir[0] : sd[0];
    sd[1] = env_light ? env_dir[1] : sd[1];
    sd[2] = env_light ? env_dir[2] : sd[2];
    lLx = env_light ? env_Le[0] : lLx;
    lLy = env_light ? env_Le[1] : lLy;
    lLz = env_light ? env_Le[2] : lLz;
#if HAS_ENVMAP
    lLox = env_light ? env_Le[0] : lLox;
    lLoy = env_light ? env_Le[1] : lLoy;
    lLoz = env_light ? env_Le[2] : lLoz;
#else
    if (two_state) { // nee_Le_in
        lLox = env_light ? light_env_constant(params_old, env_param, 0u) : lLox;
        lLoy = env_light ? light_env_constant(params_old, env_param, 1u) : lLoy;
        lLoz = env_light ? light_env_constant(params_old, env_param, 2u) : lLoz;
    }
#endif
    lparam = env_light ? env_param : lparam;
    pdf_light = env_light ? light_env_choice_pdf(&rp, env_pdf) : pdf_light;
    stmax = env_light ? INFINITY : stmax;
#endif
    // nee_eval: wo's z in the frame, the diffuse f toward it (the old state's too), nee_weight
    const float wo_lz = dot3(wo[0], wo[1], wo[2], nx, ny, nz);
    const float fx = diffuse_f(ax, wi_lz, wo_lz), fy = diffuse_f(ay, wi_lz, wo_lz),
                fz = diffuse_f(az, wi_lz, wo_lz);
    const float fox = diffuse_f(aox, wi_lz, wo_lz), foy = diffuse_f(aoy, wi_lz, wo_lz),
                foz = diffuse_f(aoz, wi_lz, wo_lz);
    const int shadow = alive && pdf_light > 0.0f &&
                       (fmax(fx, fmax(fy, fz)) > 0.0f || (two_state && fmax(fox, fmax(foy, foz)) > 0.0f));
    const float w_nee = nee_weight_of(pdf_light, diffuse_pdf(wi_lz, wo_lz));
    if (shadow) {
        WF_SET3(WF_SHADOW_O, origin[0], origin[1], origin[2]);
        WF_SET3(WF_SHADOW_D, sd[0], sd[1], sd[2]);
        WF_F(WF_SHADOW_TMAX) = stmax;
        WF_SET3(WF_CONTRIB, nee_term(bx, fx, lLx, w_nee), nee_term(by, fy, lLy, w_nee),
                nee_term(bz, fz, lLz, w_nee));
        if (two_state) { // nee_Le_in: the old state's radiance, the new state's weight
            WF_SET3(WF_CONTRIB_OLD, nee_term(box, fox, lLox, w_nee),
                    nee_term(boy, foy, lLoy, w_nee), nee_term(boz, foz, lLoz, w_nee));
        }
        if (replay) { // adjoint_nee's factors, applied by wf_replay_shadow
            WF_SET3(WF_GRAD_NEE, adjoint_nee_k(dx, bx, lLx, w_nee),
                    adjoint_nee_k(dy, by, lLy, w_nee), adjoint_nee_k(dz, bz, lLz, w_nee));
            WF_F(WF_NEE_G) = diffuse_cos(wi_lz, wo_lz);
            WF_SET3(WF_GRAD_LIGHT, adjoint_nee_light_channel(dx, bx, fx, w_nee),
                    adjoint_nee_light_channel(dy, by, fy, w_nee),
                    adjoint_nee_light_channel(dz, bz, fz, w_nee));
            WF_U(WF_LIGHT_PARAM) = lparam;
        }
    }

    // continuation_sample: bsdf_diffuse_sample's cosine-weighted direction, whose weight is the
    // albedo where it succeeds (continuation_failed)
    float dk[3];
    cosine_hemisphere(path_rand(rng, dim + DIM_BSDF), path_rand(rng, dim + DIM_BSDF + 1u), dk);
    const float pdf = cosine_hemisphere_pdf(dk[2]);
    alive = alive && diffuse_sampled(wi_lz, pdf);
    // continuation_weight_old
    float wox_c = 0.0f, woy_c = 0.0f, woz_c = 0.0f;
    if (two_state) {
        const float inv_pdf = 1.0f / pdf;
        wox_c = continuation_weight_old_channel(ax, diffuse_f(ax, wi_lz, dk[2]),
                                                diffuse_f(aox, wi_lz, dk[2]), inv_pdf);
        woy_c = continuation_weight_old_channel(ay, diffuse_f(ay, wi_lz, dk[2]),
                                                diffuse_f(aoy, wi_lz, dk[2]), inv_pdf);
        woz_c = continuation_weight_old_channel(az, diffuse_f(az, wi_lz, dk[2]),
                                                diffuse_f(aoz, wi_lz, dk[2]), inv_pdf);
        alive = alive && !(fmax(ax, fmax(ay, az)) <= 0.0f && fmax(wox_c, fmax(woy_c, woz_c)) <= 0.0f);
    } else {
        alive = alive && !(fmax(ax, fmax(ay, az)) <= 0.0f);
    }
    if (replay && alive) { // adjoint_continuation's f and d f / d albedo (bsdf_diffuse_eval)
        WF_SET3(WF_CONT_F, diffuse_f(ax, wi_lz, dk[2]), diffuse_f(ay, wi_lz, dk[2]),
                diffuse_f(az, wi_lz, dk[2]));
        WF_F(WF_CONT_G) = diffuse_cos(wi_lz, dk[2]);
    }
    const int continued = alive;
    float nbx = continuation_beta(bx, ax), nby = continuation_beta(by, ay),
          nbz = continuation_beta(bz, az);
    float nbox = continuation_beta(box, wox_c), nboy = continuation_beta(boy, woy_c),
          nboz = continuation_beta(boz, woz_c);
    // continuation_ray: frame_to_world, from the side the direction points to
    const float rdx = frame_world_component(fs[0], ft[0], nx, dk),
                rdy = frame_world_component(fs[1], ft[1], ny, dk),
                rdz = frame_world_component(fs[2], ft[2], nz, dk);
    const int same_side = dot3(rdx, rdy, rdz, ox_n, oy_n, oz_n) >= 0.0f;
    const float rox = same_side ? origin[0] : offset_component(x, -ox_n);
    const float roy = same_side ? origin[1] : offset_component(y, -oy_n);
    const float roz = same_side ? origin[2] : offset_component(z, -oz_n);
    // Russian roulette (roulette_q or roulette_q_two_state, roulette_ends)
    const int roulette = roulette_applies(&rp, depth);
    const float q_rr = two_state ? roulette_survival_two_state(nbx, nby, nbz, nbox, nboy, nboz)
                                 : roulette_survival(nbx, nby, nbz);
    alive = alive && !(roulette && roulette_ends_at(path_rand(rng, dim + DIM_RR), q_rr));
    nbx = roulette ? roulette_beta(nbx, q_rr) : nbx;
    nby = roulette ? roulette_beta(nby, q_rr) : nby;
    nbz = roulette ? roulette_beta(nbz, q_rr) : nbz;
    nbox = roulette ? roulette_beta(nbox, q_rr) : nbox;
    nboy = roulette ? roulette_beta(nboy, q_rr) : nboy;
    nboz = roulette ? roulette_beta(nboz, q_rr) : nboz;
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
