// The wavefront's path state as the host and the kernels share it (kernels/wavefront.cl,
// path/wavefront.h; core/render/wavefront.cpp sizes the buffers from WF_FLOAT_FIELDS and
// WF_UINT_FIELDS and passes WF_NO_RECORD).
#ifndef TANDEM_SHARED_WAVEFRONT_LAYOUT_H
#define TANDEM_SHARED_WAVEFRONT_LAYOUT_H

// Fields of the float state, each an array of n floats: state[field * n + path].
#define WF_OX 0u
#define WF_DX 3u
#define WF_TMIN 6u
#define WF_TMAX 7u
#define WF_BETA 8u
#define WF_L 11u
#define WF_PREV_PDF 14u
#define WF_HIT_T 15u
#define WF_HIT_U 16u
#define WF_HIT_V 17u
#define WF_SHADOW_O 18u // the shadow ray: origin, direction, tmax
#define WF_SHADOW_D 21u
#define WF_SHADOW_TMAX 24u
#define WF_CONTRIB 25u  // beta f Le w of the pending light sample
// the two-state path's previous state (wf_shade_two_state): throughput, radiance, pending term
#define WF_BETA_OLD 28u
#define WF_L_OLD 31u
#define WF_CONTRIB_OLD 34u
// the replay's (wf_shade_replay): its adjoint, and what a vertex leaves for wf_replay_shadow
#define WF_DELTA 37u      // delta / spp, times 2^s (kernels/adjoint.cl: adjoint_pass's d)
#define WF_GRAD_EMIT 40u  // d/d(Le) of the emission found: delta beta w
#define WF_GRAD_LIGHT 43u // d/d(Le) of the light sample: delta beta f w
#define WF_GRAD_NEE 46u   // the light sample's delta beta Le w (adjoint_nee_k)
#define WF_CONT_F 49u     // f of the continuation's direction
#define WF_CONT_G 52u     // its d f / d albedo, cos / pi (the same in every channel)
#define WF_TU 53u         // the vertex's texture coordinates
#define WF_TV 54u
#define WF_NEE_G 55u      // the light sample's d f / d albedo, cos / pi (as WF_CONT_G)
#define WF_FLOAT_FIELDS 56u
// Fields of the uint state.
#define WF_PRIM 0u
#define WF_FLAGS 1u
#define WF_EMIT_PARAM 2u  // the replay's: the parameters of the emission and the light sample,
#define WF_LIGHT_PARAM 3u // and the vertex's material
#define WF_MATERIAL 4u
#define WF_UINT_FIELDS 5u

/// What the adjoint's first pass records of bounce `slot` for its replay (WF_NO_RECORD: nothing):
/// the hit's t, u, v and triangle in hits[(4 slot + c) n + i], c = 0..3, and whether the light
/// sample's shadow ray was unoccluded in seen[slot n + i]. The replay retraces the same rays, so
/// it reads these instead of tracing them again: the same hits and the same bits.
#define WF_NO_RECORD 0xFFFFFFFFu

#endif // TANDEM_SHARED_WAVEFRONT_LAYOUT_H
