// Phase 4: graph coloring of the contacts (CPU twin: solver::color::color_contacts, which
// is greedy; here Jones-Plassmann-Luby). Two contacts conflict when they share a body that
// an impulse can move. Steps: per-body incidence lists (count, scan.wgsl, fill, sort),
// then one workgroup colors in rounds and permutes contact indices by color into `order`,
// so each color is a contiguous range the solver sweeps with one dispatch.

@compute @workgroup_size(64)
fn incidence_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    if moves_i(c) { atomicAdd(&ints[sim.o_inc_count + c.i], 1u); }
    if moves_j(c) { atomicAdd(&ints[sim.o_inc_count + c.j], 1u); }
}

@compute @workgroup_size(64)
fn incidence_fill(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    if moves_i(c) {
        let s = ld(sim.o_inc_count + c.i) + atomicAdd(&ints[sim.o_inc_fill + c.i], 1u);
        st(sim.o_inc_list + s, k);
    }
    if moves_j(c) {
        let s = ld(sim.o_inc_count + c.j) + atomicAdd(&ints[sim.o_inc_fill + c.j], 1u);
        st(sim.o_inc_list + s, k);
    }
}

// Sorts each body's incidence list by contact index, so that every sum over a body's
// contacts (warm start, Jacobi gather) runs in a fixed order and the step is reproducible.
@compute @workgroup_size(64)
fn incidence_sort(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if b >= sim.n_bodies { return; }
    let lo = ld(sim.o_inc_count + b);
    let hi = ld(sim.o_inc_count + b + 1u);
    for (var s = lo + 1u; s < hi; s++) {
        let v = ld(sim.o_inc_list + s);
        var r = s;
        loop {
            if r == lo { break; }
            let u = ld(sim.o_inc_list + r - 1u);
            if u < v { break; }
            st(sim.o_inc_list + r, u);
            r -= 1u;
        }
        st(sim.o_inc_list + r, v);
    }
}

// Random but reproducible priority of a contact: a hash of its key, so a persisting
// contact keeps its priority from step to step.
fn priority(c: Contact) -> u32 {
    var h = c.i * 0x9E3779B1u ^ (c.disk_j + 0x7F4A7C15u);
    h ^= h >> 16u;
    h *= 0x85EBCA6Bu;
    h ^= h >> 13u;
    h *= 0xC2B2AE35u;
    h ^= h >> 16u;
    return h;
}

// True when contact a beats contact b (priority, then index).
fn beats(pa: u32, a: u32, pb: u32, b: u32) -> bool {
    return pa > pb || (pa == pb && a > b);
}

// Bit mask of the colors in [base, base + 32) used by the colored neighbours of k along
// body b's incidence list; sets `blocked` when an uncolored neighbour has higher priority.
struct Scan { mask: u32, blocked: bool }

fn scan_body(b: u32, k: u32, pk: u32, base: u32) -> Scan {
    var out = Scan(0u, false);
    for (var s = ld(sim.o_inc_count + b); s < ld(sim.o_inc_count + b + 1u); s++) {
        let e = ld(sim.o_inc_list + s);
        if e == k { continue; }
        let col = contacts[e].color;
        if col == UNSET {
            if beats(priority(contacts[e]), e, pk, k) { out.blocked = true; }
        } else if col >= base && col < base + 32u {
            out.mask |= 1u << (col - base);
        }
    }
    return out;
}

var<workgroup> wg_left: atomic<u32>;
var<workgroup> wg_colors: atomic<u32>;
var<workgroup> wg_rounds: u32;
var<workgroup> wg_left_u: u32;

@compute @workgroup_size(256)
fn color_jpl(@builtin(local_invocation_index) t: u32) {
    let nc = n_contacts();
    for (var k = t; k < nc; k += 256u) { contacts[k].color = UNSET; }
    if t == 0u { atomicStore(&wg_colors, 0u); wg_rounds = 0u; }
    storageBarrier();
    workgroupBarrier();
    loop {
        if t == 0u { atomicStore(&wg_left, 0u); }
        workgroupBarrier();
        // Round, phase 1: every uncolored contact that beats all its uncolored neighbours
        // picks the smallest color its colored neighbours do not use. `order` holds the
        // choices until phase 2, so no thread sees a color chosen in the same round.
        for (var k = t; k < nc; k += 256u) {
            let c = contacts[k];
            if c.color != UNSET { st(sim.o_order + k, UNSET); continue; }
            let pk = priority(c);
            var choice = UNSET;
            var base = 0u;
            loop {
                var used = 0u;
                var blocked = false;
                if moves_i(c) {
                    let r = scan_body(c.i, k, pk, base);
                    used |= r.mask;
                    blocked = r.blocked;
                }
                if moves_j(c) {
                    let r = scan_body(c.j, k, pk, base);
                    used |= r.mask;
                    blocked = blocked || r.blocked;
                }
                if blocked { break; }
                if used != 0xffffffffu {
                    choice = base + firstTrailingBit(~used);
                    break;
                }
                base += 32u;
            }
            st(sim.o_order + k, choice);
            if choice == UNSET { atomicAdd(&wg_left, 1u); }
        }
        storageBarrier();
        workgroupBarrier();
        // Phase 2: commit the choices.
        for (var k = t; k < nc; k += 256u) {
            let choice = ld(sim.o_order + k);
            if choice != UNSET {
                contacts[k].color = choice;
                atomicMax(&wg_colors, choice + 1u);
            }
        }
        if t == 0u { wg_rounds += 1u; }
        storageBarrier();
        if t == 0u { wg_left_u = atomicLoad(&wg_left); }
        let left = workgroupUniformLoad(&wg_left_u);
        if left == 0u { break; }
    }
    // Count per color, prefix sum, scatter into `order` (colors beyond capacity are
    // reported and the host grows the color table and redoes the step).
    let n_colors = atomicLoad(&wg_colors);
    let maxc = sim.max_colors;
    for (var k = t; k < nc; k += 256u) {
        let col = contacts[k].color;
        if col < maxc { atomicAdd(&ints[sim.o_color_count + col], 1u); }
    }
    storageBarrier();
    workgroupBarrier();
    if t == 0u {
        var sum = 0u;
        for (var col = 0u; col < min(n_colors, maxc); col++) {
            let v = ld(sim.o_color_count + col);
            st(sim.o_color_count + col, sum);
            sum += v;
        }
        st(sim.o_color_count + min(n_colors, maxc), sum);
        st(sim.o_status + ST_COLORS, n_colors);
        st(sim.o_status + ST_ROUNDS, wg_rounds);
    }
    storageBarrier();
    workgroupBarrier();
    for (var k = t; k < nc; k += 256u) {
        let col = contacts[k].color;
        if col < maxc {
            let s = ld(sim.o_color_count + col) + atomicAdd(&ints[sim.o_color_fill + col], 1u);
            st(sim.o_order + s, k);
        }
    }
}
