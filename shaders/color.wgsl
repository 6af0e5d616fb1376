// Phase 4: graph coloring of the contacts (CPU twin: solver::color::color_contacts, which
// is greedy; here Jones-Plassmann-Luby). Two contacts conflict when they share a body that
// an impulse can move. Steps: per-body incidence lists (count, scan.wgsl, fill, rank),
// then one dispatch per coloring round, then count, offsets and scatter of the contact
// indices by color into `order`.

@compute @workgroup_size(WG)
fn incidence_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    if moves_i(c) { atomicAdd(&ints[sim.o_inc_count + c.i], 1u); }
    if moves_j(c) { atomicAdd(&ints[sim.o_inc_count + c.j], 1u); }
}

@compute @workgroup_size(WG)
fn incidence_fill(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    if moves_i(c) {
        let s = ld(sim.o_inc_count + c.i) + atomicAdd(&ints[sim.o_inc_fill + c.i], 1u);
        st(sim.o_inc_tmp + s, k);
    }
    if moves_j(c) {
        let s = ld(sim.o_inc_count + c.j) + atomicAdd(&ints[sim.o_inc_fill + c.j], 1u);
        st(sim.o_inc_tmp + s, k);
    }
}

// Puts contact k at its rank (by contact index) in the sorted incidence list of each body
// it moves, so that every sum over a body's contacts (warm start, Jacobi gather) runs in a
// fixed order and the step is reproducible. One thread per contact scans its bodies'
// unsorted lists: a force-driven wall touching m disks costs m iterations per thread,
// where a per-body insertion sort cost up to m^2 / 2 in one thread, past llvmpipe's
// per-invocation loop budget (65,535) from about 360 wall contacts.
fn rank_in(b: u32, k: u32) {
    let lo = ld(sim.o_inc_count + b);
    let hi = ld(sim.o_inc_count + b + 1u);
    var rank = 0u;
    for (var s = lo; s < hi; s++) {
        if ld(sim.o_inc_tmp + s) < k { rank++; }
    }
    st(sim.o_inc_list + lo + rank, k);
}

@compute @workgroup_size(WG)
fn incidence_rank(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    if moves_i(c) { rank_in(c.i, k); }
    if moves_j(c) { rank_in(c.j, k); }
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

// How contact k sees its neighbour e at the start of round r: colored (its color) or not
// (UNSET). Colors live in ints[o_color + k] as `color | round << 16`; a neighbour colored
// during round r itself counts as uncolored, so every thread of a round sees the state at
// the round's start whatever the order the threads run in. Such a neighbour always beats
// k (it beat all its uncolored neighbours, k among them), so k is blocked either way.
fn color_at_start(e: u32, r: u32) -> u32 {
    let v = ld(sim.o_color + e);
    if v == UNSET || (v >> 16u) >= r { return UNSET; }
    return v & 0xffffu;
}

// Bit mask of the colors in [base, base + 32) used by the colored neighbours of k along
// body b's incidence list; sets `blocked` when an uncolored neighbour has higher priority.
struct Scan { mask: u32, blocked: bool }

fn scan_body(b: u32, k: u32, pk: u32, base: u32, r: u32) -> Scan {
    var out = Scan(0u, false);
    for (var s = ld(sim.o_inc_count + b); s < ld(sim.o_inc_count + b + 1u); s++) {
        let e = ld(sim.o_inc_list + s);
        if e == k { continue; }
        let col = color_at_start(e, r);
        if col == UNSET {
            if beats(priority(contacts[e]), e, pk, k) { out.blocked = true; }
        } else if col >= base && col < base + 32u {
            out.mask |= 1u << (col - base);
        }
    }
    return out;
}

// Round 0 of the coloring: the seeds (docs/gpu.md: seeded with last step's colors, so that
// most contacts keep theirs). A persisting contact keeps the color it brought from the
// warm start unless a neighbour with the same seed beats it; new contacts and the losers
// start uncolored. The kept seeds share no body (of two equal neighbours the loser drops),
// and the rounds only add colors around them. ints[o_left + r] counts the contacts still
// uncolored after round r (the counters are cleared with the step's scratch).
@compute @workgroup_size(WG)
fn color_seed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    var keep = c.color < sim.max_colors;
    if keep {
        let pk = priority(c);
        for (var side = 0u; side < 2u && keep; side++) {
            let b = select(c.j, c.i, side == 0u);
            if !select(moves_j(c), moves_i(c), side == 0u) { continue; }
            for (var s = ld(sim.o_inc_count + b); s < ld(sim.o_inc_count + b + 1u); s++) {
                let e = ld(sim.o_inc_list + s);
                if e != k && contacts[e].color == c.color && beats(priority(contacts[e]), e, pk, k) {
                    keep = false;
                    break;
                }
            }
        }
    }
    if keep {
        st(sim.o_color + k, c.color);
    } else {
        st(sim.o_color + k, UNSET);
        atomicAdd(&ints[sim.o_left], 1u);
    }
}

// Jones-Plassmann-Luby round r = args.a (one dispatch per round, one thread per contact,
// so the work of a thread does not grow with the sample: a single workgroup looping over
// every contact ran past llvmpipe's per-invocation loop budget of 65,535 iterations from
// about 58,000 contacts and stopped halfway). Every uncolored contact that beats all its
// uncolored neighbours takes the smallest color its colored neighbours do not use.
@compute @workgroup_size(WG)
fn color_round(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    let r = args.a;
    if k >= n_contacts() { return; }
    // Rounds are recorded ahead of need: once one leaves nothing, the rest are no-ops.
    if ld(sim.o_left + r - 1u) == 0u { return; }
    if ld(sim.o_color + k) != UNSET { return; }
    let c = contacts[k];
    let pk = priority(c);
    var base = 0u;
    loop {
        var used = 0u;
        var blocked = false;
        if moves_i(c) {
            let s = scan_body(c.i, k, pk, base, r);
            used |= s.mask;
            blocked = s.blocked;
        }
        if moves_j(c) {
            let s = scan_body(c.j, k, pk, base, r);
            used |= s.mask;
            blocked = blocked || s.blocked;
        }
        if blocked {
            atomicAdd(&ints[sim.o_left + r], 1u);
            return;
        }
        if used != 0xffffffffu {
            st(sim.o_color + k, (base + firstTrailingBit(~used)) | (r << 16u));
            return;
        }
        base += 32u;
    }
}

// After the rounds: the color of each contact into its record, the count per color and
// the number of colors (colors beyond capacity are reported and the host grows the color
// table and redoes the step; an unfinished coloring is reported through ST_LEFT).
@compute @workgroup_size(WG)
fn color_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let v = ld(sim.o_color + k);
    if v == UNSET { return; }
    let col = v & 0xffffu;
    contacts[k].color = col;
    atomicMax(&ints[sim.o_status + ST_COLORS], col + 1u);
    if col < sim.max_colors { atomicAdd(&ints[sim.o_color_count + col], 1u); }
}

// Prefix sum of the per-color counts (a few dozen colors: one thread), the rounds used
// and the contacts left uncolored after the last recorded round args.a.
@compute @workgroup_size(1)
fn color_offsets() {
    let n_colors = min(ld(sim.o_status + ST_COLORS), sim.max_colors);
    var sum = 0u;
    for (var col = 0u; col < n_colors; col++) {
        let v = ld(sim.o_color_count + col);
        st(sim.o_color_count + col, sum);
        sum += v;
    }
    st(sim.o_color_count + n_colors, sum);
    // Rounds that colored something: none when every seed was kept.
    let last = args.a;
    var rounds = last;
    for (var r = 0u; r <= last; r++) {
        if ld(sim.o_left + r) == 0u { rounds = r; break; }
    }
    st(sim.o_status + ST_ROUNDS, rounds);
    st(sim.o_status + ST_LEFT, ld(sim.o_left + last));
}

// Permutes contact indices by color into `order`, so each color is a contiguous range the
// solver sweeps with one dispatch. The order inside a color is arbitrary and harmless:
// contacts of one color share no movable body, so their updates commute.
@compute @workgroup_size(WG)
fn color_scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let v = ld(sim.o_color + k);
    if v == UNSET { return; }
    let col = v & 0xffffu;
    if col < sim.max_colors {
        let s = ld(sim.o_color_count + col) + atomicAdd(&ints[sim.o_color_fill + col], 1u);
        st(sim.o_order + s, k);
    }
}
