// Test-only entry points (tests/gpu_kernels.rs), composed like a phase shader with
// shaders/common.wgsl in front, so they run the very functions the kernels call, on inputs
// the test chooses.

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
