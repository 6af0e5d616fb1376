// Shared declarations for every phase: the binding table, the records (identical to the
// #[repr(C)] Pod structs in src/gpu/buffers.rs), the contact frame and the local
// Signorini-Coulomb solution (CPU twins: src/contact/mod.rs, src/solver/law.rs).
//
// All kernels share one bind group layout so that a single bind group serves the whole
// step. Integer scratch lives in one atomic u32 buffer (`ints`) and float scratch in one
// f32 buffer (`floats`), cut into regions whose offsets come from `sim` (recomputed by the
// host whenever a capacity grows): this keeps the layout at 6 storage buffers, under the
// WebGPU default of 8 per stage.

// The constants shared with Rust are not declared here: the host puts them in front of
// this file, generated from their Rust source (cdlab::gpu::wgsl_prelude in src/gpu/mod.rs).
// They are the body kinds (KIND_*), the status words ST_* (ints[o_status + ST_*], read back
// after detection and coloring; buffers::status), the entries DISP_* (3 words each) of the
// solve's dispatch arguments at ints[o_disp] (buffers::disp), and the slots of the float
// regions the host reads back (buffers::float_slot): floats[f_red + FR_*] (reduce.wgsl),
// floats[f_grid + FG_*] (grid.wgsl), floats[f_conv + FC_*] (solve.wgsl).

// Internal to the shaders.
const UNSET: u32 = 0xffffffffu;

struct Sim {
    n_disks: u32, n_walls: u32, n_bodies: u32, k_slots: u32,
    cap_contacts: u32, cap_cells: u32, max_colors: u32, strips: u32,
    top: u32, bottom: u32, o_cell_start: u32, o_cell_fill: u32,
    o_items: u32, o_cell_of: u32, o_dcount: u32, o_slots: u32,
    o_inc_count: u32, o_inc_fill: u32, o_inc_list: u32, o_status: u32,
    o_color_count: u32, o_color_fill: u32, o_order: u32, o_per_disk: u32,
    f_d2: u32, f_r2: u32, f_fresh: u32, f_wall: u32,
    f_red: u32, f_grid: u32, f_conv: u32, jacobi: u32,
    dt: f32, theta: f32, alert: f32, r_max: f32,
    gx: f32, gy: f32, mu_disk: f32, mu_wall: f32,
    e_n: f32, e_t: f32, sigma3: f32, relax: f32,
    strip_sum_r0: f32, strip_sum_r1: f32, gap_tol: f32, gs_relax: f32,
    o_color: u32, o_left: u32, max_rounds: u32, o_inc_tmp: u32,
    f_deep: u32, deep_gap: f32, deep_sweeps: u32, deep_budget: u32,
    o_disp: u32, max_iter: u32, tol: f32, velocity_tol: f32,
    r_min: f32, o_outline: u32, one: f32, o_color_map: u32,
}

// Per-dispatch arguments (a region to scan, a color to sweep), bound at a dynamic offset.
struct Args { a: u32, b: u32, c: u32, d: u32 }

// Positions relative to the sample centre are two floats (x + x_lo, y + y_lo; walls
// px + px_lo, py + py_lo): one f32 far from the centre rounds away a step of a few
// micrometres. Read relative positions through disk_delta and wall_offset, move with ds_add.
struct Disk {
    x: f32, y: f32, theta: f32, radius: f32,
    inv_mass: f32, inv_inertia: f32, mass: f32, kind: u32,
    glued: u32, strip: i32, fx: f32, fy: f32,
    torque: f32, x_lo: f32, y_lo: f32, _p0: f32,
}

// A plane wall; its velocity is vel[n_disks + w] (generalized body numbering).
struct Wall {
    nx: f32, ny: f32, px: f32, py: f32,
    inv_mass: f32, force: f32, is_active: u32, forced: u32,
    px_lo: f32, py_lo: f32, _p0: f32, _p1: f32,
}

// Same fields and meaning as crate::contact::Contact (f32).
struct Contact {
    i: u32, j: u32, disk_j: u32, color: u32,
    nx: f32, ny: f32, gap: f32, ri: f32,
    rj: f32, mi: f32, mj: f32, ma: f32,
    ax: f32, ay: f32, ki: f32, kj: f32,
    wnn: f32, wtt: f32, wnt: f32, mu: f32,
    un0: f32, ut0: f32, bias_n: f32, bias_t: f32,
    rn: f32, rt: f32, deep: u32, _p1: f32,
}

// The parameters are read-only storage, not uniform buffers: Mesa lavapipe 22.x specializes
// a shader to the values of the uniform buffers its branches depend on, compiles it again
// at every dispatch and never frees the copies: the host memory of a GPU run grew without
// bound (tests/gpu_memory.rs keeps it flat). Storage buffers are never specialized.
@group(0) @binding(0) var<storage, read> sim: Sim;
@group(0) @binding(1) var<storage, read_write> disks: array<Disk>;
@group(0) @binding(2) var<storage, read_write> walls: array<Wall>;
// Generalized velocities (vx, vy, spin, 0), five regions of n_bodies: 0 state (end of
// step), 1 start of step, 2 free, 3 current iterate, 4 the iterate kept for the velocity
// test (solve.wgsl, save_iterate).
@group(0) @binding(3) var<storage, read_write> vel: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> ints: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> contacts: array<Contact>;
@group(0) @binding(6) var<storage, read_write> floats: array<f32>;
// Previous step's contacts for the warm start: offsets per disk (n_disks + 1), then
// records (disk_j, rn bits, rt bits, color) in key order.
@group(0) @binding(7) var<storage, read_write> prev: array<u32>;
@group(1) @binding(0) var<storage, read> args: Args;

// a + b as an unevaluated sum (s, e) with s = fl(a + b) and e its exact rounding error
// (Knuth's TwoSum, with no condition on the magnitudes). Written plainly, a compiler that
// treats f32 addition as associative (Mesa's NIR does, for every operation SPIR-V does not
// mark exact, and WGSL cannot mark one) folds (a + b) - a to b and e to 0: the low word is
// then lost at the first step. Multiplying by sim.one, 1.0 read from memory, leaves every
// value unchanged and gives it no expression to fold.
fn two_sum(a: f32, b: f32) -> vec2<f32> {
    let s = a + b;
    let bb = s * sim.one - a;
    let e = (a - (s - bb) * sim.one) + (b - bb);
    return vec2<f32>(s, e);
}

// The two-float (hi, lo) moved by d, renormalized so that lo stays within half an ulp of
// hi: d is kept to the last bit of lo, not to the last bit of hi.
fn ds_add(hi: f32, lo: f32, d: f32) -> vec2<f32> {
    let s = two_sum(hi, d);
    return two_sum(s.x, s.y + lo);
}

// Position of disk a relative to disk b. The high words' difference is exact for bodies
// closer than their distance from the centre (Sterbenz), so the low words decide the
// last bits, as in f64. The factor sim.one keeps a compiler from regrouping the sum as
// (a.x + a.x_lo) - (b.x + b.x_lo), which would round at the f32 spacing of the positions.
fn disk_delta(a: Disk, b: Disk) -> vec2<f32> {
    let hi = vec2<f32>(a.x, a.y) - vec2<f32>(b.x, b.y);
    return hi * sim.one + (vec2<f32>(a.x_lo, a.y_lo) - vec2<f32>(b.x_lo, b.y_lo));
}

// Position of disk a relative to wall w's point (as disk_delta).
fn wall_offset(a: Disk, w: Wall) -> vec2<f32> {
    let hi = vec2<f32>(a.x, a.y) - vec2<f32>(w.px, w.py);
    return hi * sim.one + (vec2<f32>(a.x_lo, a.y_lo) - vec2<f32>(w.px_lo, w.py_lo));
}

// Signed distance of disk a's surface from wall w (its gap), positive inside.
fn wall_gap(a: Disk, w: Wall) -> f32 {
    return dot(wall_offset(a, w), vec2<f32>(w.nx, w.ny)) - a.radius;
}

fn ld(k: u32) -> u32 { return atomicLoad(&ints[k]); }
fn st(k: u32, v: u32) { atomicStore(&ints[k], v); }
fn n_contacts() -> u32 { return min(ld(sim.o_status + ST_CONTACTS), sim.cap_contacts); }
fn vel_at(region: u32, b: u32) -> vec4<f32> { return vel[region * sim.n_bodies + b]; }
fn set_vel(region: u32, b: u32, v: vec4<f32>) { vel[region * sim.n_bodies + b] = v; }

// Relative velocity (U_n, U_t) of the contact points for body velocities vi, vj.
fn relative_velocity(c: Contact, vi: vec4<f32>, vj: vec4<f32>) -> vec2<f32> {
    let dx = vi.x - vj.x;
    let dy = vi.y - vj.y;
    let un = dx * c.nx + dy * c.ny;
    let ut = dx * c.ny - dy * c.nx + vi.z * c.ri + vj.z * c.rj;
    return vec2<f32>(un, ut);
}

// Velocity change of body i for impulse increments (drn, drt).
fn dv_i(c: Contact, drn: f32, drt: f32) -> vec4<f32> {
    let px = drn * c.nx + drt * c.ny;
    let py = drn * c.ny - drt * c.nx;
    return vec4<f32>(c.mi * px, c.mi * py, c.ki * drt, 0.0);
}

// Velocity change of body j for impulse increments (drn, drt) (it receives -P).
fn dv_j(c: Contact, drn: f32, drt: f32) -> vec4<f32> {
    let px = drn * c.nx + drt * c.ny;
    let py = drn * c.ny - drt * c.nx;
    let pa = c.ma * (px * c.ax + py * c.ay);
    return vec4<f32>(-(c.mj * px + pa * c.ax), -(c.mj * py + pa * c.ay), c.kj * drt, 0.0);
}

// Kinematic and fixed bodies are never written: this is what lets one color share them.
fn moves_j(c: Contact) -> bool { return c.mj != 0.0 || c.ma != 0.0 || c.kj != 0.0; }
fn moves_i(c: Contact) -> bool { return c.mi != 0.0 || c.ki != 0.0; }

// The offset of the normal law for a step (CPU twin: engine::normal_bias): an open gap may
// close during the step but not beyond (docs/method.md), a closed one gets the restitution
// offset e_n min(U_n, 0).
fn normal_bias(gap: f32, un: f32, theta: f32, dt: f32, e_n: f32) -> f32 {
    if gap > 0.0 { return max((gap + (1.0 - theta) * dt * un) / (theta * dt), 0.0); }
    return e_n * min(un, 0.0);
}

// Exact local solution with a diagonal Delassus block (every disk-disk and disk-plane
// contact): R_n = max(0, -ufn / W_nn), R_t = clamp(-uft / W_tt, -mu R_n, mu R_n).
fn solve_diagonal(wnn: f32, wtt: f32, ufn: f32, uft: f32, mu: f32) -> vec2<f32> {
    var rn = 0.0;
    if ufn < 0.0 { rn = -ufn / wnn; }
    let lim = mu * rn;
    var rt = 0.0;
    if wtt > 0.0 { rt = clamp(-uft / wtt, -lim, lim); }
    return vec2<f32>(rn, rt);
}

// Exact local solution for a full 2x2 block (a disk glued to a force-driven wall touching
// a disk obliquely), by cases: separation, stick, slide either way (CPU: law::solve_block).
fn solve_block(wnn: f32, wtt: f32, wnt: f32, ufn: f32, uft: f32, mu: f32) -> vec2<f32> {
    if ufn >= 0.0 { return vec2<f32>(0.0, 0.0); }
    let det = wnn * wtt - wnt * wnt;
    if det > 0.0 {
        let rn = (-ufn * wtt + uft * wnt) / det;
        let rt = (-uft * wnn + ufn * wnt) / det;
        if rn >= 0.0 && abs(rt) <= mu * rn { return vec2<f32>(rn, rt); }
    }
    var best = vec2<f32>(0.0, 0.0);
    for (var k = 0; k < 2; k++) {
        let s = select(-1.0, 1.0, k == 0);
        let denom = wnn - s * mu * wnt;
        if denom <= 0.0 { continue; }
        let rn = -ufn / denom;
        let ut = uft + (wnt - s * mu * wtt) * rn;
        if rn >= 0.0 && ut * s >= 0.0 { return vec2<f32>(rn, -s * mu * rn); }
        best = vec2<f32>(rn, -s * mu * rn);
    }
    return best;
}

fn solve_local(c: Contact, ufn: f32, uft: f32) -> vec2<f32> {
    if c.wnt == 0.0 { return solve_diagonal(c.wnn, c.wtt, ufn, uft, c.mu); }
    return solve_block(c.wnn, c.wtt, c.wnt, ufn, uft, c.mu);
}

// The new local impulses of contact c from the current velocities (its own removed).
fn local_update(c: Contact, vi: vec4<f32>, vj: vec4<f32>) -> vec2<f32> {
    let u = relative_velocity(c, vi, vj);
    let ufn = u.x - c.wnn * c.rn - c.wnt * c.rt + c.bias_n;
    let uft = u.y - c.wnt * c.rn - c.wtt * c.rt + c.bias_t;
    return solve_local(c, ufn, uft);
}
