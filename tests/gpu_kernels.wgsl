// Test-only entry points (tests/gpu_kernels.rs), composed like a phase shader with
// shaders/common.wgsl and shaders/detect.wgsl in front, so they run the very functions the
// kernels call, on inputs the test chooses.

// The local law of contact k, with the velocities of its bodies in vel[2k] (i) and
// vel[2k + 1] (j): writes the new impulses (R_n, R_t) to floats[2k] and floats[2k + 1].
@compute @workgroup_size(WG)
fn probe_law(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&contacts) { return; }
    let r = local_update(contacts[k], vel[2u * k], vel[2u * k + 1u]);
    floats[2u * k] = r.x;
    floats[2u * k + 1u] = r.y;
}

// The normal offset of record k, floats[6k..6k + 6] = (gap, U_n, theta, dt, e_n, result).
@compute @workgroup_size(WG)
fn probe_bias(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&floats) / 6u { return; }
    let b = 6u * k;
    floats[b + 5u] = normal_bias(floats[b], floats[b + 1u], floats[b + 2u], floats[b + 3u], floats[b + 4u]);
}

// The Delassus block of contact k as build_contacts fills it (detect.wgsl's `delassus`, on
// the record's masses, levers and frame): writes (W_nn, W_tt, W_nt) to floats[3k..3k + 3].
@compute @workgroup_size(WG)
fn probe_delassus(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&contacts) { return; }
    var c = contacts[k];
    delassus(&c);
    floats[3u * k] = c.wnn;
    floats[3u * k + 1u] = c.wtt;
    floats[3u * k + 2u] = c.wnt;
}
