// Phase 6: theta scheme (CPU twin: CpuEngine::integrate). One thread per generalized body.

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
        walls[w].px += dt * v.x;
        walls[w].py += dt * v.y;
        set_vel(0u, b, vp);
        return;
    }
    let d = disks[b];
    if d.glued != NOT_GLUED {
        // Glued disks move exactly as their wall does, so they never drift from it.
        let wb = nd + d.glued;
        let v = (1.0 - th) * vel_at(1u, wb) + th * vel_at(3u, wb);
        disks[b].x += dt * v.x;
        disks[b].y += dt * v.y;
        set_vel(0u, b, vec4<f32>(vel_at(3u, wb).xy, 0.0, 0.0));
    } else if d.kind == KIND_KINEMATIC {
        disks[b].x += dt * vm.x;
        disks[b].y += dt * vm.y;
        disks[b].theta += dt * vm.z;
    } else if d.kind == KIND_FREE {
        let v = (1.0 - th) * vm + th * vp;
        disks[b].x += dt * v.x;
        disks[b].y += dt * v.y;
        disks[b].theta += dt * v.z;
        set_vel(0u, b, vp);
    }
}
