// The secondary boundary term's reservoirs (core/render/boundary_reuse.h) in the parameter state,
// so that a checkpoint carries them and a resumed run continues bit for bit. They live on in their
// SecondaryReservoirs between checkpoints (the passes read and advance them there); a checkpoint
// copies them in first (store), a resume takes them back (load). One set serves every view: the
// reservoirs are keyed by the grid cell of their boundary point, in world space ("Amortizing
// Samples in Physics-Based Inverse Rendering using ReSTIR", Wang et al. 2023, Sec. 7).
#pragma once

namespace tandem {

class ParamState;
class SecondaryReservoirs;

/// Registers the named buffers (none previous yet): call before restoring a checkpoint.
void attach_secondary_reuse(ParamState& state);
/// Copies `reservoirs`' state into `state`'s buffers (blocks for the downloads).
void store_secondary_reuse(const SecondaryReservoirs& reservoirs, ParamState& state);
/// Takes it back into `reservoirs`: after a checkpoint was restored into `state`.
void load_secondary_reuse(ParamState& state, SecondaryReservoirs& reservoirs);

} // namespace tandem
