// Phase 3: contact detection with warm start (CPU twin: contact::detect::detect and
// CpuEngine::prepare_contacts).
//
// Each free disk i owns the pairs in which it is the contact's body i (CPU rule: of two
// free disks the lower index, else the free one) and lists their partners in its own K
// slots, sorted, so no two threads write the same slots and the compacted list comes out
// in the CPU's key order (i, partner). Walls are partners n_disks + w, after every disk.

fn grid_dims_d() -> vec2<u32> {
    return vec2<u32>(bitcast<u32>(floats[sim.f_grid + FG_NX]), bitcast<u32>(floats[sim.f_grid + FG_NY]));
}

// Inserts `q` in disk i's sorted slot list of current length n (when it fits).
fn insert_partner(base: u32, n: u32, q: u32) {
    if n >= sim.k_slots { return; }
    var s = n;
    loop {
        if s == 0u { break; }
        let prev_q = ld(base + s - 1u);
        if prev_q < q { break; }
        st(base + s, prev_q);
        s -= 1u;
    }
    st(base + s, q);
}

@compute @workgroup_size(WG)
fn detect(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let nd = sim.n_disks;
    if i >= nd { return; }
    let di = disks[i];
    var n = 0u;
    if di.kind == KIND_FREE {
        let base = sim.o_slots + i * sim.k_slots;
        let dims = grid_dims_d();
        let c = ld(sim.o_cell_of + i);
        let cx = c % dims.x;
        let cy = c / dims.x;
        for (var y = max(cy, 1u) - 1u; y < min(cy + 2u, dims.y); y++) {
            for (var x = max(cx, 1u) - 1u; x < min(cx + 2u, dims.x); x++) {
                let cc = y * dims.x + x;
                for (var s = ld(sim.o_cell_start + cc); s < ld(sim.o_cell_start + cc + 1u); s++) {
                    let q = ld(sim.o_items + s);
                    if q == i { continue; }
                    let dq = disks[q];
                    if dq.kind == KIND_FREE && q < i { continue; }
                    let delta = disk_delta(di, dq);
                    let reach = di.radius + dq.radius + sim.alert;
                    let dist2 = dot(delta, delta);
                    if dist2 >= reach * reach || dist2 == 0.0 { continue; }
                    insert_partner(base, n, q);
                    n += 1u;
                }
            }
        }
        for (var w = 0u; w < sim.n_walls; w++) {
            let wall = walls[w];
            if wall.is_active == 0u { continue; }
            let gap = wall_gap(di, wall);
            if gap < sim.alert {
                insert_partner(base, n, nd + w);
                n += 1u;
            }
        }
        atomicMax(&ints[sim.o_status + ST_SLOTS_NEED], n);
    }
    st(sim.o_dcount + i, min(n, sim.k_slots));
}

// Writes the contact count and the indirect dispatch size of per-contact kernels (copied
// by the host into the indirect-argument buffer).
@compute @workgroup_size(1)
fn contact_args() {
    let total = ld(sim.o_dcount + sim.n_disks);
    st(sim.o_status + ST_CONTACTS, total);
    let n = min(total, sim.cap_contacts);
    st(sim.o_status + ST_ARGS, (n + WG - 1u) / WG);
    st(sim.o_status + ST_ARGS + 1u, 1u);
    st(sim.o_status + ST_ARGS + 2u, 1u);
}

struct Side { body: u32, lever: f32, inv_mass: f32, axial: f32, axis: vec2<f32>, k: f32 }

// The dynamic side of disk k: a glued disk acts through its wall's single degree of
// freedom (along the wall normal, when the wall is force-driven) and does not spin.
fn disk_side(k: u32) -> Side {
    let d = disks[k];
    if d.glued != NOT_GLUED {
        let w = walls[d.glued];
        return Side(sim.n_disks + d.glued, 0.0, 0.0, w.inv_mass, vec2<f32>(w.nx, w.ny), 0.0);
    }
    return Side(k, d.radius, d.inv_mass, 0.0, vec2<f32>(0.0), d.radius * d.inv_inertia);
}

fn delassus(c: ptr<function, Contact>) {
    let an = (*c).ax * (*c).nx + (*c).ay * (*c).ny;
    let at = (*c).ax * (*c).ny - (*c).ay * (*c).nx;
    (*c).wnn = (*c).mi + (*c).mj + (*c).ma * an * an;
    (*c).wtt = (*c).mi + (*c).mj + (*c).ma * at * at + (*c).ri * (*c).ki + (*c).rj * (*c).kj;
    (*c).wnt = (*c).ma * an * at;
}

// Compacts disk i's partners into contact records: frame, gap, Delassus block, start-of-
// step velocities, law offsets, and the previous step's impulses for the same partner.
@compute @workgroup_size(WG)
fn build_contacts(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let nd = sim.n_disks;
    if i >= nd { return; }
    let off = ld(sim.o_dcount + i);
    let cnt = ld(sim.o_dcount + i + 1u) - off;
    let di = disks[i];
    let si = disk_side(i);
    let p0 = prev[i];
    let p1 = prev[i + 1u];
    var cursor = p0;
    for (var s = 0u; s < cnt; s++) {
        let slot = off + s;
        if slot >= sim.cap_contacts { break; }
        let q = ld(sim.o_slots + i * sim.k_slots + s);
        var c: Contact;
        c.i = si.body;
        c.disk_j = q;
        c.color = UNSET;
        c.ri = si.lever;
        c.mi = si.inv_mass;
        c.ki = si.k;
        if q < nd {
            let dq = disks[q];
            let sj = disk_side(q);
            let delta = disk_delta(di, dq);
            let dist = length(delta);
            c.j = sj.body;
            c.nx = delta.x / dist;
            c.ny = delta.y / dist;
            c.gap = dist - di.radius - dq.radius;
            c.rj = sj.lever;
            c.mj = sj.inv_mass;
            c.ma = sj.axial;
            c.ax = sj.axis.x;
            c.ay = sj.axis.y;
            c.kj = sj.k;
            c.mu = sim.mu_disk;
        } else {
            let w = walls[q - nd];
            c.j = q;
            c.nx = w.nx;
            c.ny = w.ny;
            c.gap = wall_gap(di, w);
            c.rj = 0.0;
            c.mj = 0.0;
            c.kj = 0.0;
            c.ma = select(0.0, w.inv_mass, w.forced != 0u);
            c.ax = w.nx;
            c.ay = w.ny;
            c.mu = sim.mu_wall;
        }
        delassus(&c);
        let u = relative_velocity(c, vel_at(1u, c.i), vel_at(1u, c.j));
        c.un0 = u.x;
        c.ut0 = u.y;
        c.bias_n = normal_bias(c.gap, u.x, sim.theta, sim.dt, sim.e_n);
        // Not for an exact zero gap: -0.0 has the sign bit set, its bits would exceed every
        // positive overlap's and hide them from the host's overlap limit.
        if c.gap < 0.0 {
            atomicMax(&ints[sim.o_status + ST_OVERLAP], bitcast<u32>(-c.gap));
        }
        c.bias_t = sim.e_t * u.y;
        // Warm start: both lists are sorted by partner, so one forward walk finds it. A
        // persisting contact also brings its last color, the coloring's seed.
        c.rn = 0.0;
        c.rt = 0.0;
        loop {
            if cursor >= p1 { break; }
            let at = nd + 1u + PREV_STRIDE * cursor;
            let pq = prev[at];
            if pq > q { break; }
            if pq == q {
                c.rn = bitcast<f32>(prev[at + 1u]);
                c.rt = clamp(bitcast<f32>(prev[at + 2u]), -c.mu * c.rn, c.mu * c.rn);
                c.color = prev[at + 3u];
            }
            cursor++;
        }
        contacts[slot] = c;
    }
}

// Saves this step's impulses and colors (by disk, in key order; PREV_STRIDE words per
// contact: partner, R_n bits, R_t bits, color) for the next step's warm start and coloring
// seed.
@compute @workgroup_size(WG)
fn save_prev(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    let nd = sim.n_disks;
    if k <= nd { prev[k] = min(ld(sim.o_dcount + k), sim.cap_contacts); }
    if k < n_contacts() {
        let c = contacts[k];
        let at = nd + 1u + PREV_STRIDE * k;
        prev[at] = c.disk_j;
        prev[at + 1u] = bitcast<u32>(c.rn);
        prev[at + 2u] = bitcast<u32>(c.rt);
        prev[at + 3u] = c.color;
    }
}
