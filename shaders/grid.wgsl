// Phase 2: the uniform cell grid (CPU twin: CellGrid::build): bounds, cell count,
// prefix sum (scan.wgsl), scatter. The order of disks inside a cell is not deterministic
// here (atomics), which is harmless: detection sorts each disk's partners.

var<workgroup> lo_x: array<f32, 256>;
var<workgroup> lo_y: array<f32, 256>;
var<workgroup> hi_x: array<f32, 256>;
var<workgroup> hi_y: array<f32, 256>;

// The four extremes of the workgroup's values, in lo_x[0], lo_y[0], hi_x[0], hi_y[0].
fn reduce_box(t: u32, lx: f32, ly: f32, hx: f32, hy: f32) {
    lo_x[t] = lx; lo_y[t] = ly; hi_x[t] = hx; hi_y[t] = hy;
    workgroupBarrier();
    for (var off = 128u; off > 0u; off >>= 1u) {
        if t < off {
            lo_x[t] = min(lo_x[t], lo_x[t + off]);
            lo_y[t] = min(lo_y[t], lo_y[t + off]);
            hi_x[t] = max(hi_x[t], hi_x[t + off]);
            hi_y[t] = max(hi_y[t], hi_y[t + off]);
        }
        workgroupBarrier();
    }
}

// Bounding box of the centres, part 1: a workgroup per 256 disks writes its box (x and y
// lows, then highs, as bits) to ints[args.a + 4 * workgroup]. One workgroup walking every
// disk left each of its threads waiting on some 200 loads in turn at 50,000 disks, one of
// the single-workgroup walks that made most of a step's detection time on an H200
// (docs/gpu.md, "Where the device's time goes"). Minima and maxima are exact, so the box
// does not depend on how the disks are cut.
@compute @workgroup_size(256)
fn grid_partial(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
) {
    let k = wg.x * 256u + t;
    var p = vec2<f32>(3.0e38);
    var q = vec2<f32>(-3.0e38);
    if k < args.b {
        p = vec2<f32>(disks[k].x, disks[k].y);
        q = p;
    }
    reduce_box(t, p.x, p.y, q.x, q.y);
    if t == 0u {
        let at = args.a + 4u * wg.x;
        st(at, bitcast<u32>(lo_x[0]));
        st(at + 1u, bitcast<u32>(lo_y[0]));
        st(at + 2u, bitcast<u32>(hi_x[0]));
        st(at + 3u, bitcast<u32>(hi_y[0]));
    }
}

// Part 2, one workgroup: the box of part 1's boxes (one per 256 of the args.b disks), and
// the grid built on it, written to floats[f_grid..]: origin x, y, cell side, nx, ny (bits).
// Same sizing rule as the CPU: a cell at least the largest diameter plus the alert
// distance, enlarged so the cells stay within capacity.
@compute @workgroup_size(256)
fn grid_bounds(@builtin(local_invocation_index) t: u32) {
    var lx = 3.0e38;
    var ly = 3.0e38;
    var hx = -3.0e38;
    var hy = -3.0e38;
    let boxes = (args.b + 255u) / 256u;
    for (var b = t; b < boxes; b += 256u) {
        let at = args.a + 4u * b;
        lx = min(lx, bitcast<f32>(ld(at)));
        ly = min(ly, bitcast<f32>(ld(at + 1u)));
        hx = max(hx, bitcast<f32>(ld(at + 2u)));
        hy = max(hy, bitcast<f32>(ld(at + 3u)));
    }
    reduce_box(t, lx, ly, hx, hy);
    if t == 0u {
        var o = vec2<f32>(lo_x[0], lo_y[0]);
        var ext = vec2<f32>(hi_x[0], hi_y[0]) - o;
        if sim.n_disks == 0u { o = vec2<f32>(0.0); ext = vec2<f32>(0.0); }
        let min_cell = 2.0 * sim.r_max + sim.alert;
        let max_cells = f32(sim.cap_cells);
        var cell = min_cell;
        if (ext.x / cell + 1.0) * (ext.y / cell + 1.0) > max_cells {
            cell = max(sqrt(ext.x * ext.y / max_cells), min_cell) * 1.5;
        }
        // An elongated cloud can still need too many cells: enlarge until it fits.
        var nx = u32(ext.x / cell) + 1u;
        var ny = u32(ext.y / cell) + 1u;
        while nx * ny > sim.cap_cells {
            cell *= 1.5;
            nx = u32(ext.x / cell) + 1u;
            ny = u32(ext.y / cell) + 1u;
        }
        floats[sim.f_grid + FG_ORIGIN_X] = o.x;
        floats[sim.f_grid + FG_ORIGIN_Y] = o.y;
        floats[sim.f_grid + FG_CELL] = cell;
        floats[sim.f_grid + FG_NX] = bitcast<f32>(nx);
        floats[sim.f_grid + FG_NY] = bitcast<f32>(ny);
    }
}

fn grid_dims() -> vec2<u32> {
    return vec2<u32>(bitcast<u32>(floats[sim.f_grid + FG_NX]), bitcast<u32>(floats[sim.f_grid + FG_NY]));
}

// The high words of the position alone (common.wgsl): cells are at least the reach wide
// and a high word is within half an f32 spacing of the position (3.8e-6 m at 107 m), so
// only a pair at the very edge of the alert distance can land in cells that are not
// neighbours, as with a single f32.
fn cell_coords(k: u32) -> vec2<u32> {
    let o = vec2<f32>(floats[sim.f_grid + FG_ORIGIN_X], floats[sim.f_grid + FG_ORIGIN_Y]);
    let cell = floats[sim.f_grid + FG_CELL];
    let dims = grid_dims();
    let p = (vec2<f32>(disks[k].x, disks[k].y) - o) / cell;
    return min(vec2<u32>(max(p, vec2<f32>(0.0))), dims - vec2<u32>(1u));
}

// Counts the disks of every cell (into the cell-start region, scanned next).
@compute @workgroup_size(WG)
fn grid_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= sim.n_disks { return; }
    let cc = cell_coords(k);
    let c = cc.y * grid_dims().x + cc.x;
    st(sim.o_cell_of + k, c);
    atomicAdd(&ints[sim.o_cell_start + c], 1u);
}

// Places every disk in its cell's range of the item list.
@compute @workgroup_size(WG)
fn grid_scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= sim.n_disks { return; }
    let c = ld(sim.o_cell_of + k);
    let slot = ld(sim.o_cell_start + c) + atomicAdd(&ints[sim.o_cell_fill + c], 1u);
    st(sim.o_items + slot, k);
}
