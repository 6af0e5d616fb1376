// Phase 5, the iterations (CPU twin: solver::sweep). Colored projected Gauss-Seidel runs
// one dispatch per color (contacts of a color share no movable body, so the threads of a
// dispatch never write the same velocity); relaxed Jacobi solves every contact from the
// same velocities and rebuilds each body's velocity by a gather over its own sorted
// incidence list (no float atomics, reproducible).
//
// These kernels write only velocities, contacts and floats. They are composed with the
// integer arena, the disks, the walls and the warm-start records bound read-only
// (pipeline::Binds::Sweep): the integers are then plain loads, which a GPU may cache,
// instead of atomic ones, since nothing writes them during these dispatches.

// Impulse contribution of contact e to body b's velocity, with impulses (rn, rt).
fn contribution(b: u32, c: Contact, rn: f32, rt: f32) -> vec4<f32> {
    if c.i == b { return dv_i(c, rn, rt); }
    return dv_j(c, rn, rt);
}

// v = v_free + M^-1 sum H R over the body's contacts (warm start and Jacobi).
@compute @workgroup_size(WG)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if b >= sim.n_bodies { return; }
    var v = vel_at(2u, b);
    for (var s = ld(sim.o_inc_count + b); s < ld(sim.o_inc_count + b + 1u); s++) {
        let c = contacts[ld(sim.o_inc_list + s)];
        v += contribution(b, c, c.rn, c.rt);
    }
    set_vel(3u, b, v);
}

// The contact at position i of color col in the sweep order, or UNSET past its end.
fn color_member(col: u32, i: u32) -> u32 {
    let start = ld(sim.o_color_count + col);
    let end = ld(sim.o_color_count + col + 1u);
    if start + i >= end { return UNSET; }
    return ld(sim.o_order + start + i);
}

// Gauss-Seidel update of contact k at the iteration's relaxation, with its convergence
// terms (args.b is 1 for the relaxed iterations, which move by sim.gs_relax; CPU twin:
// SolverParams::relax_at).
fn sweep_one(k: u32) {
    let u = gs_update(k, select(1.0, sim.gs_relax, args.b == 1u));
    floats[sim.f_d2 + k] = u.x * u.x + u.y * u.y;
    floats[sim.f_r2 + k] = dot(u.zw, u.zw);
}

// One large color of a Gauss-Seidel sweep: entry args.a of the sweep order of colors
// (solve_args, big colors first).
@compute @workgroup_size(WG)
fn sweep_color(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = color_member(ld(sim.o_color_map + args.a), gid.x);
    if k == UNSET { return; }
    sweep_one(k);
}

var<workgroup> tail_colors: u32;

// The small colors of a Gauss-Seidel sweep (at most WG contacts each), one after the other
// in one workgroup with a barrier between two: the same sweep as one dispatch per color,
// at the cost of one dispatch. Force-driven walls make many such colors (every contact on
// such a wall shares its body, so each takes a color of its own), and a dispatch costs the
// host about as much to record whatever it does (docs/gpu.md, "Measured on hardware").
// The count reaches every thread through workgroupUniformLoad, as barriers need.
@compute @workgroup_size(WG)
fn sweep_tail(@builtin(local_invocation_index) t: u32) {
    if t == 0u { tail_colors = ld(sim.o_status + ST_TAIL); }
    let n = workgroupUniformLoad(&tail_colors);
    let big = ld(sim.o_status + ST_BIG);
    for (var c = 0u; c < n; c++) {
        let k = color_member(ld(sim.o_color_map + big + c), t);
        if k != UNSET { sweep_one(k); }
        storageBarrier();
    }
}

// Threads of sweep_all: more than WG, since one workgroup walks every contact.
const WG_ALL: u32 = 4u * WG;

var<workgroup> all_colors: u32;
var<workgroup> all_range: vec2<u32>;

// A whole Gauss-Seidel sweep in one workgroup: every nonempty color in the sweep order of
// solve_args (large colors, then small ones), a barrier between two, so the same sweep as
// sweep_color and sweep_tail in one dispatch. It serves the iterations recorded past what
// the last steps typically needed: a dispatch past the solve's end costs the device about
// as much as one with work (docs/gpu.md, "Measured on hardware"), so such iterations are
// recorded as one dispatch each instead of one per color. Counts reach every thread
// through workgroupUniformLoad, as barriers need; storageBarrier is a control barrier, so
// every thread has read a color's range before thread 0 writes the next.
@compute @workgroup_size(WG_ALL)
fn sweep_all(@builtin(local_invocation_index) t: u32) {
    if t == 0u { all_colors = ld(sim.o_status + ST_BIG) + ld(sim.o_status + ST_TAIL); }
    let n = workgroupUniformLoad(&all_colors);
    for (var c = 0u; c < n; c++) {
        if t == 0u {
            let col = ld(sim.o_color_map + c);
            all_range = vec2<u32>(ld(sim.o_color_count + col), ld(sim.o_color_count + col + 1u));
        }
        let r = workgroupUniformLoad(&all_range);
        for (var i = r.x + t; i < r.y; i += WG_ALL) {
            sweep_one(ld(sim.o_order + i));
        }
        storageBarrier();
    }
}

// Jacobi, part 1: every contact from the same velocities, relaxed by sim.relax.
@compute @workgroup_size(WG)
fn jacobi_solve(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    let r = local_update(c, vel_at(3u, c.i), vel_at(3u, c.j));
    let old = vec2<f32>(c.rn, c.rt);
    let fresh = old + sim.relax * (r - old);
    let d = fresh - old;
    floats[sim.f_fresh + 2u * k] = fresh.x;
    floats[sim.f_fresh + 2u * k + 1u] = fresh.y;
    floats[sim.f_d2 + k] = dot(d, d);
    floats[sim.f_r2 + k] = dot(fresh, fresh);
}

// Jacobi, part 2: commit the relaxed impulses (the gather then rebuilds the velocities).
@compute @workgroup_size(WG)
fn jacobi_commit(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    contacts[k].rn = floats[sim.f_fresh + 2u * k];
    contacts[k].rt = floats[sim.f_fresh + 2u * k + 1u];
}

// The velocity test (CPU twin: solver::convergence::VelocityTest): the iterate before the last
// iteration of a batch goes to region 4.
@compute @workgroup_size(WG)
fn save_iterate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if b >= sim.n_bodies { return; }
    set_vel(4u, b, vel_at(3u, b));
}

var<workgroup> dv_max: array<f32, 256>;

// Largest change of a body's velocity since save_iterate, rim speed r |omega| included (walls
// have no rim), to floats[f_conv + FC_DV]. One workgroup.
@compute @workgroup_size(256)
fn velocity_change(@builtin(local_invocation_index) t: u32) {
    var m = 0.0;
    for (var b = t; b < sim.n_bodies; b += 256u) {
        let d = vel_at(3u, b) - vel_at(4u, b);
        var lever = 0.0;
        if b < sim.n_disks { lever = disks[b].radius; }
        m = max(m, sqrt(d.x * d.x + d.y * d.y + lever * lever * d.z * d.z));
    }
    dv_max[t] = m;
    workgroupBarrier();
    for (var off = 128u; off > 0u; off >>= 1u) {
        if t < off {
            dv_max[t] = max(dv_max[t], dv_max[t + off]);
        }
        workgroupBarrier();
    }
    if t == 0u {
        floats[sim.f_conv + FC_DV] = dv_max[0];
    }
}
