// Phase 6: theta scheme (CPU twin: CpuEngine::integrate). One thread per generalized body.

// Moves disk b by d. Positions are two floats (common.wgsl): a plain `x += d` would round
// a step of a few micrometres to the f32 spacing of x, 7.6e-6 m at 100 m from the centre.
fn move_disk(b: u32, d: vec2<f32>) {
    let x = ds_add(disks[b].x, disks[b].x_lo, d.x);
    let y = ds_add(disks[b].y, disks[b].y_lo, d.y);
    disks[b].x = x.x;
    disks[b].x_lo = x.y;
    disks[b].y = y.x;
    disks[b].y_lo = y.y;
}

// Moves wall w's point by d (two floats, as move_disk).
fn move_wall(w: u32, d: vec2<f32>) {
    let x = ds_add(walls[w].px, walls[w].px_lo, d.x);
    let y = ds_add(walls[w].py, walls[w].py_lo, d.y);
    walls[w].px = x.x;
    walls[w].px_lo = x.y;
    walls[w].py = y.x;
    walls[w].py_lo = y.y;
}

@compute @workgroup_size(WG)
fn integrate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    let nd = sim.n_disks;
    if b >= sim.n_bodies { return; }
    let dt = sim.dt;
    let th = sim.theta;
    let vm = vel_at(1u, b);
    let vp = vel_at(3u, b);
    if b >= nd {
        let w = b - nd;
        let v = (1.0 - th) * vm + th * vp;
        move_wall(w, dt * v.xy);
        set_vel(0u, b, vp);
        return;
    }
    let d = disks[b];
    if d.glued != NOT_GLUED {
        // Glued disks move exactly as their wall does, so they never drift from it.
        let wb = nd + d.glued;
        let v = (1.0 - th) * vel_at(1u, wb) + th * vel_at(3u, wb);
        move_disk(b, dt * v.xy);
        set_vel(0u, b, vec4<f32>(vel_at(3u, wb).xy, 0.0, 0.0));
    } else if d.kind == KIND_KINEMATIC {
        move_disk(b, dt * vm.xy);
        disks[b].theta += dt * vm.z;
    } else if d.kind == KIND_FREE {
        let v = (1.0 - th) * vm + th * vp;
        move_disk(b, dt * v.xy);
        disks[b].theta += dt * v.z;
        set_vel(0u, b, vp);
    }
}
