// Phase 1: free velocities (CPU twin: CpuEngine::velocities, follow_walls and
// Loading::apply). One thread per generalized body (disks, then walls).

// Strip load of disk k from the current sample height: each strip carries sigma3 * H,
// shared in proportion to the radii (the sums of radii are constant and come from the host).
fn strip_force(k: u32) -> vec2<f32> {
    let s = disks[k].strip;
    if s == 0 { return vec2<f32>(0.0, 0.0); }
    let t = sim.top;
    let b = sim.bottom;
    let h = (walls[t].py - walls[b].py) + (walls[t].py_lo - walls[b].py_lo);
    let total = sim.sigma3 * h;
    var sum_r = sim.strip_sum_r0;
    if s > 0 { sum_r = sim.strip_sum_r1; }
    return vec2<f32>(-f32(s) * total * disks[k].radius / sum_r, 0.0);
}

@compute @workgroup_size(WG)
fn free_velocity(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    let nd = sim.n_disks;
    if b >= sim.n_bodies { return; }
    var v = vel_at(0u, b);
    var vfree = v;
    if b < nd {
        let d = disks[b];
        if d.glued != NOT_GLUED {
            // Glued disks take their wall's velocity and do not spin.
            let w = vel_at(0u, nd + d.glued);
            v = vec4<f32>(w.x, w.y, 0.0, 0.0);
            set_vel(0u, b, v);
        }
        vfree = v;
        if d.kind == KIND_FREE {
            var f = vec2<f32>(d.fx, d.fy);
            // While the strips are on, their loads are the only forces on free disks: a
            // disk that has left a strip carries none.
            if sim.strips != 0u {
                f = strip_force(b);
                disks[b].fx = f.x;
                disks[b].fy = f.y;
            }
            let acc = f * d.inv_mass + vec2<f32>(sim.gx, sim.gy);
            vfree = v + sim.dt * vec4<f32>(acc.x, acc.y, d.torque * d.inv_inertia, 0.0);
        }
    } else {
        let w = walls[b - nd];
        if w.forced != 0u {
            let a = sim.dt * w.force * w.inv_mass;
            vfree = v + vec4<f32>(w.nx * a, w.ny * a, 0.0, 0.0);
        }
    }
    set_vel(1u, b, v);
    set_vel(2u, b, vfree);
    set_vel(3u, b, vfree);
}
