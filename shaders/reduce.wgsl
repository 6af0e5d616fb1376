// Phase 7: reductions (CPU twin: backend::reduce::Accumulator and CpuEngine::wall_impulses).
// Only these small sums leave the device during a run.

var<workgroup> sum_x: array<f32, 256>;
var<workgroup> sum_y: array<f32, 256>;

// Tree sum of each thread's (x, y) over the workgroup; every thread gets the total.
fn wg_sum2(t: u32, v: vec2<f32>) -> vec2<f32> {
    sum_x[t] = v.x;
    sum_y[t] = v.y;
    workgroupBarrier();
    for (var off = 128u; off > 0u; off >>= 1u) {
        if t < off {
            sum_x[t] += sum_x[t + off];
            sum_y[t] += sum_y[t + off];
        }
        workgroupBarrier();
    }
    let out = vec2<f32>(sum_x[0], sum_y[0]);
    workgroupBarrier();
    return out;
}

// Impulse exerted by the contacts on wall w (workgroup w), glued disks included, added to
// the run's accumulator floats[f_wall + 2w ..].
@compute @workgroup_size(256)
fn wall_impulse(@builtin(local_invocation_index) t: u32, @builtin(workgroup_id) wg: vec3<u32>) {
    let body = sim.n_disks + wg.x;
    var p = vec2<f32>(0.0);
    let n = n_contacts();
    for (var k = t; k < n; k += 256u) {
        let c = contacts[k];
        if c.j == body {
            p -= c.rn * vec2<f32>(c.nx, c.ny) + c.rt * vec2<f32>(c.ny, -c.nx);
        }
    }
    let s = wg_sum2(t, p);
    if t == 0u {
        floats[sim.f_wall + 2u * wg.x] += s.x;
        floats[sim.f_wall + 2u * wg.x + 1u] += s.y;
    }
}

var<workgroup> cnt: array<atomic<u32>, 8>;
var<workgroup> ov_max: atomic<u32>;
// Micromechanical counts: 0 force-carrying disk-disk contacts, 1 strong ones, 2.. the
// orientation histogram's MICRO_BINS bins.
var<workgroup> mcnt: array<atomic<u32>, FR_MICRO_COUNTS>;

const MICRO_PI: f32 = 3.14159265358979;
const MICRO_BINS: u32 = 18u;

// The symmetric part of a b^T as (xx, xy, yy).
fn sym_outer(a: vec2<f32>, b: vec2<f32>) -> vec3<f32> {
    return vec3<f32>(a.x * b.x, 0.5 * (a.x * b.y + a.y * b.x), a.y * b.y);
}

const SLIDE_EPS: f32 = 1e-6;
const FORCE_THRESHOLD: f32 = 1e-6;

// Counts, overlaps, kinetic energy and strip positions of the last step, to
// floats[f_red + FR_*] (the slots are named in common.wgsl; counts as u32 bits), then
// the micromechanical counts and sums from FR_MICRO on (see micro_sums).
@compute @workgroup_size(256)
fn reduce_final(@builtin(local_invocation_index) t: u32) {
    let nd = sim.n_disks;
    let n = n_contacts();
    if t < 8u { atomicStore(&cnt[t], 0u); }
    if t < FR_MICRO_COUNTS { atomicStore(&mcnt[t], 0u); }
    if t == 0u { atomicStore(&ov_max, 0u); }
    for (var k = t; k < nd; k += 256u) { st(sim.o_per_disk + k, 0u); }
    storageBarrier();
    var loaded = vec2<f32>(0.0);
    for (var k = t; k < n; k += 256u) {
        let rn = contacts[k].rn;
        if rn > 0.0 { loaded += vec2<f32>(rn, 1.0); }
    }
    let tot = wg_sum2(t, loaded);
    let mean_rn = tot.x / max(tot.y, 1.0);
    let threshold = FORCE_THRESHOLD * mean_rn;
    var ov = vec2<f32>(0.0);
    for (var k = t; k < n; k += 256u) {
        let c = contacts[k];
        if c.gap < 0.0 {
            ov += vec2<f32>(1.0, -c.gap);
            atomicMax(&ov_max, bitcast<u32>(-c.gap));
        }
        let disk_disk = c.disk_j < nd;
        let carrying = c.rn > threshold;
        if carrying {
            atomicAdd(&ints[sim.o_per_disk + c.i], 1u);
            if disk_disk { atomicAdd(&ints[sim.o_per_disk + c.disk_j], 1u); }
        }
        if !disk_disk { continue; }
        if !carrying && c.gap <= sim.gap_tol {
            atomicAdd(&cnt[2], 1u);
        } else if carrying && c.rn > 0.0 {
            if abs(c.rt) >= c.mu * c.rn * (1.0 - SLIDE_EPS) {
                atomicAdd(&cnt[1], 1u);
            } else {
                atomicAdd(&cnt[0], 1u);
            }
        }
    }
    let ovs = wg_sum2(t, ov);
    micro_sums(t, threshold);
    storageBarrier();
    workgroupBarrier();
    var ke = 0.0;
    var ket = 0.0;
    var kec = 0.0;
    var sx = vec2<f32>(0.0);
    var sc = vec2<f32>(0.0);
    for (var k = t; k < nd; k += 256u) {
        let d = disks[k];
        if d.kind == KIND_FREE {
            atomicAdd(&cnt[4], 1u);
            if ld(sim.o_per_disk + k) >= 2u {
                atomicAdd(&cnt[3], 1u);
                kec += 0.5 * d.mass * dot(vel_at(0u, k).xy, vel_at(0u, k).xy);
            }
            let v = vel_at(0u, k);
            ket += 0.5 * d.mass * dot(v.xy, v.xy);
            ke += 0.5 * d.mass * dot(v.xy, v.xy) + 0.25 * d.mass * d.radius * d.radius * v.z * v.z;
        }
        if d.strip < 0 { sx.x += d.x + d.x_lo; sc.x += 1.0; }
        if d.strip > 0 { sx.y += d.x + d.x_lo; sc.y += 1.0; }
    }
    let kes = wg_sum2(t, vec2<f32>(ke, ket));
    let kcs = wg_sum2(t, vec2<f32>(kec, 0.0));
    let sxs = wg_sum2(t, sx);
    let scs = wg_sum2(t, sc);
    if t == 0u {
        floats[sim.f_red + FR_MEAN_RN] = mean_rn;
        floats[sim.f_red + FR_ROLLING] = bitcast<f32>(atomicLoad(&cnt[0]));
        floats[sim.f_red + FR_SLIDING] = bitcast<f32>(atomicLoad(&cnt[1]));
        floats[sim.f_red + FR_ZERO_FORCE] = bitcast<f32>(atomicLoad(&cnt[2]));
        floats[sim.f_red + FR_CONNECTED] = bitcast<f32>(atomicLoad(&cnt[3]));
        floats[sim.f_red + FR_FREE] = bitcast<f32>(atomicLoad(&cnt[4]));
        floats[sim.f_red + FR_OVERLAP_COUNT] = ovs.x;
        floats[sim.f_red + FR_OVERLAP_SUM] = ovs.y;
        floats[sim.f_red + FR_OVERLAP_MAX] = bitcast<f32>(atomicLoad(&ov_max));
        floats[sim.f_red + FR_KINETIC] = kes.x;
        floats[sim.f_red + FR_STRIP_X_LEFT] = sxs.x;
        floats[sim.f_red + FR_STRIP_X_RIGHT] = sxs.y;
        floats[sim.f_red + FR_STRIP_N_LEFT] = scs.x;
        floats[sim.f_red + FR_STRIP_N_RIGHT] = scs.y;
        floats[sim.f_red + FR_TRANSLATIONAL] = kes.y;
        floats[sim.f_red + FR_CONNECTED_ENERGY] = kcs.x;
    }
}

// The micromechanical sums of the last step's contacts (CPU twin:
// measure::micro::MicroSums::of, in impulses: the host divides by dt), to
// floats[f_red + FR_MICRO ..]: +0 force-carrying disk-disk contacts, +1 strong ones (u32
// bits), +2..+19 orientation bins over [0, pi) (u32 bits); then from FR_MICRO_SUMS the sums
// over the force-carrying contacts as (xx, xy, yy): +0 n n, +3 R_n, +4 R_n n n, +7 R_t
// sym(t n), +10 R l over every contact (walls included), +13 R l over the disk-disk ones,
// +16 R l over the strong ones.
// `threshold` is the force-carrying threshold of reduce_final; the strong threshold, the
// mean R_n of the force-carrying disk-disk contacts, takes a first pass.
fn micro_sums(t: u32, threshold: f32) {
    let nd = sim.n_disks;
    let n = n_contacts();
    var dd = vec2<f32>(0.0);
    for (var k = t; k < n; k += 256u) {
        let c = contacts[k];
        if c.disk_j < nd && c.rn > threshold { dd += vec2<f32>(c.rn, 1.0); }
    }
    let dds = wg_sum2(t, dd);
    let strong = select(0.0, dds.x / max(dds.y, 1.0), dds.y > 0.0);
    var nn = vec3<f32>(0.0);
    var fs = 0.0;
    var fnn = vec3<f32>(0.0);
    var ftn = vec3<f32>(0.0);
    var st = vec3<f32>(0.0);
    var sdd = vec3<f32>(0.0);
    var sst = vec3<f32>(0.0);
    for (var k = t; k < n; k += 256u) {
        let c = contacts[k];
        if !(c.rn > threshold) { continue; }
        let nv = vec2<f32>(c.nx, c.ny);
        let tg = vec2<f32>(c.ny, -c.nx);
        let disk = c.disk_j < nd;
        var len = disks[c.i].radius + c.gap;
        if disk { len += disks[c.disk_j].radius; }
        let fl = len * sym_outer(c.rn * nv + c.rt * tg, nv);
        st += fl;
        if !disk { continue; }
        atomicAdd(&mcnt[0], 1u);
        let o = sym_outer(nv, nv);
        nn += o;
        fs += c.rn;
        fnn += c.rn * o;
        ftn += c.rt * sym_outer(tg, nv);
        sdd += fl;
        if c.rn > strong {
            atomicAdd(&mcnt[1], 1u);
            sst += fl;
        }
        var a = atan2(c.ny, c.nx);
        if a < 0.0 { a += MICRO_PI; }
        if a >= MICRO_PI { a = 0.0; }
        let b = min(u32(floor(a / MICRO_PI * f32(MICRO_BINS))), MICRO_BINS - 1u);
        atomicAdd(&mcnt[2u + b], 1u);
    }
    let s0 = wg_sum2(t, nn.xy);
    let s1 = wg_sum2(t, vec2<f32>(nn.z, fs));
    let s2 = wg_sum2(t, fnn.xy);
    let s3 = wg_sum2(t, vec2<f32>(fnn.z, ftn.x));
    let s4 = wg_sum2(t, ftn.yz);
    let s5 = wg_sum2(t, st.xy);
    let s6 = wg_sum2(t, vec2<f32>(st.z, sdd.x));
    let s7 = wg_sum2(t, sdd.yz);
    let s8 = wg_sum2(t, sst.xy);
    let s9 = wg_sum2(t, vec2<f32>(sst.z, 0.0));
    workgroupBarrier();
    if t == 0u {
        for (var b = 0u; b < FR_MICRO_COUNTS; b++) {
            floats[sim.f_red + FR_MICRO + b] = bitcast<f32>(atomicLoad(&mcnt[b]));
        }
        var v = array<f32, 19>(
            s0.x, s0.y, s1.x, s1.y, s2.x, s2.y, s3.x, s3.y, s4.x, s4.y,
            s5.x, s5.y, s6.x, s6.y, s7.x, s7.y, s8.x, s8.y, s9.x,
        );
        for (var k = 0u; k < FR_MICRO_SUM_COUNT; k++) {
            floats[sim.f_red + FR_MICRO_SUMS + k] = v[k];
        }
    }
}

// The strips' outer edges (CPU twin: backend::reduce::strip_outer_edges): the outlines of
// the left and right strips' disks sampled at heights y0 + (i + 1/2) h between the bottom
// and the top wall, h about r_min / 2, and their means over the heights where both are set.
// Each height keeps the outermost point of the strip's disks the horizontal line crosses,
// with an atomic min (left) or max (right) on order-preserving bits of the f32 abscissa.

// The heights: bottom y0, spacing h, count n (at least 16, at most OUTLINE_BINS).
fn outline_heights() -> vec3<f32> {
    let y0 = walls[sim.bottom].py + walls[sim.bottom].py_lo;
    let y1 = walls[sim.top].py + walls[sim.top].py_lo;
    let n = clamp(ceil((y1 - y0) / (0.5 * sim.r_min)), 16.0, f32(OUTLINE_BINS));
    return vec3<f32>(y0, (y1 - y0) / n, n);
}

// f32 to u32 bits that sort as the floats do (negative floats reversed).
fn sortable(x: f32) -> u32 {
    let b = bitcast<u32>(x);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

fn unsortable(b: u32) -> f32 {
    return bitcast<f32>(select(~b, b & 0x7fffffffu, (b & 0x80000000u) != 0u));
}

// Every height unset: the left outline at the largest bits, the right one at 0.
@compute @workgroup_size(WG)
fn outline_clear(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= OUTLINE_BINS { return; }
    st(sim.o_outline + i, 0xffffffffu);
    st(sim.o_outline + OUTLINE_BINS + i, 0u);
}

// The heights y0 + (i + 1/2) h that disk d crosses, as the range [x, y) of i (empty when
// it crosses none).
fn crossed_heights(d: Disk, hs: vec3<f32>) -> vec2<u32> {
    let y = d.y + d.y_lo;
    let first = max(ceil((y - d.radius - hs.x) / hs.y - 0.5), 0.0);
    let last = min(floor((y + d.radius - hs.x) / hs.y - 0.5), hs.z - 1.0);
    if last < first { return vec2<u32>(0u, 0u); }
    return vec2<u32>(u32(first), u32(last) + 1u);
}

// Half the chord of disk d along height i.
fn half_chord(d: Disk, hs: vec3<f32>, i: u32) -> f32 {
    let dy = hs.x + (f32(i) + 0.5) * hs.y - (d.y + d.y_lo);
    return sqrt(max(d.radius * d.radius - dy * dy, 0.0));
}

// One thread per disk of a strip: the heights its disk crosses.
@compute @workgroup_size(WG)
fn strip_outline(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= sim.n_disks { return; }
    let d = disks[k];
    if d.strip == 0 { return; }
    let hs = outline_heights();
    let x = d.x + d.x_lo;
    let span = crossed_heights(d, hs);
    for (var i = span.x; i < span.y; i++) {
        let half = half_chord(d, hs, i);
        if d.strip < 0 {
            atomicMin(&ints[sim.o_outline + i], sortable(x - half));
        } else {
            atomicMax(&ints[sim.o_outline + OUTLINE_BINS + i], sortable(x + half));
        }
    }
}

// One workgroup: the sums of both outlines over the heights where both are set, and their
// count, to floats[f_red + FR_EDGE_*].
@compute @workgroup_size(256)
fn outline_sum(@builtin(local_invocation_index) t: u32) {
    let n = u32(outline_heights().z);
    var s = vec2<f32>(0.0);
    var m = 0u;
    for (var i = t; i < n; i += 256u) {
        let l = ld(sim.o_outline + i);
        let r = ld(sim.o_outline + OUTLINE_BINS + i);
        if l != 0xffffffffu && r != 0u {
            s += vec2<f32>(unsortable(l), unsortable(r));
            m += 1u;
        }
    }
    let tot = wg_sum2(t, s);
    let count = wg_sum2(t, vec2<f32>(f32(m), 0.0));
    if t == 0u {
        floats[sim.f_red + FR_EDGE_LEFT] = tot.x;
        floats[sim.f_red + FR_EDGE_RIGHT] = tot.y;
        floats[sim.f_red + FR_EDGE_COUNT] = bitcast<f32>(u32(count.x));
    }
}

// The strips' members, found on the device (CPU twin: backend::reduce::strip_members), so
// that a refresh of the strips reads back one word per disk instead of the scene. Part 1,
// after outline_clear, a thread per free disk: the outline of all free disks, its leftmost
// point at each height in the left bins and its rightmost in the right ones.
@compute @workgroup_size(WG)
fn free_outline(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= sim.n_disks { return; }
    let d = disks[k];
    if d.kind != KIND_FREE { return; }
    let hs = outline_heights();
    let x = d.x + d.x_lo;
    let span = crossed_heights(d, hs);
    for (var i = span.x; i < span.y; i++) {
        let half = half_chord(d, hs, i);
        atomicMin(&ints[sim.o_outline + i], sortable(x - half));
        atomicMax(&ints[sim.o_outline + OUTLINE_BINS + i], sortable(x + half));
    }
}

// Part 2, a thread per disk: -1 for a free disk whose centre lies within the strip
// thickness (args.a, f32 bits) of the left edge at its height, +1 of the right edge, 0
// otherwise, to the per-disk scratch (ints[o_per_disk + k]). The edge at a height is the
// outermost point of the outline within half the thickness above or below it. Unset
// heights hold the extreme bits (outline_clear), which the min and max pass over; a free
// disk sets the heights it crosses, so its own window is never empty.
@compute @workgroup_size(WG)
fn strip_classify(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= sim.n_disks { return; }
    let d = disks[k];
    var tag = 0;
    if d.kind == KIND_FREE {
        let t = bitcast<f32>(args.a);
        let hs = outline_heights();
        let n = u32(hs.z);
        let x = d.x + d.x_lo;
        let y = d.y + d.y_lo;
        let i = u32(clamp(floor((y - hs.x) / hs.y), 0.0, hs.z - 1.0));
        let reach = u32(ceil(0.5 * t / hs.y));
        let lo = select(0u, i - reach, i >= reach);
        let hi = min(i + reach + 1u, n);
        var left = 0xffffffffu;
        var right = 0u;
        for (var j = lo; j < hi; j++) {
            left = min(left, ld(sim.o_outline + j));
            right = max(right, ld(sim.o_outline + OUTLINE_BINS + j));
        }
        if left == 0xffffffffu || x < unsortable(left) + t {
            tag = -1;
        } else if right == 0u || x > unsortable(right) - t {
            tag = 1;
        }
    }
    st(sim.o_per_disk + k, bitcast<u32>(tag));
}

// A refresh of the strips taken into the disk records: the tags in the per-disk scratch
// (strip_classify's, or the host's), one word per disk.
@compute @workgroup_size(WG)
fn set_strips(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= sim.n_disks { return; }
    disks[k].strip = bitcast<i32>(ld(sim.o_per_disk + k));
}
