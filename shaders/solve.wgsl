// Phase 5, the solver's bookkeeping (CPU twin: solver::sweep, solver::convergence): the
// dispatch arguments of the solve, the convergence test closing each block of iterations
// and the local updates of deep contacts. The iterations themselves are in sweep.wgsl.
// Convergence sums are per contact and reduced in index order by one workgroup.

// Local updates of deep contacts (CPU twin: the end of solver::sweep::solve), part 1: after
// the iterations, mark each loaded contact overlapping by more than sim.deep_gap, and count
// them. Contacts with a full 2x2 block (glued walls) are left out, as on the CPU. Each deep
// contact is also filed at the head of its color's range of `order`, in deep_list (any
// order within a color: see part 2): color_scatter left the color's fill counter at the
// color's size, and counting on from there gives the slot.
@compute @workgroup_size(WG)
fn deep_mark(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= n_contacts() { return; }
    let c = contacts[k];
    let deep = c.rn > 0.0 && c.gap < -sim.deep_gap && c.wnt == 0.0 && c.ma == 0.0;
    contacts[k].deep = u32(deep);
    if deep {
        atomicAdd(&ints[sim.o_status + ST_DEEP], 1u);
        let start = ld(sim.o_color_count + c.color);
        let size = ld(sim.o_color_count + c.color + 1u) - start;
        let slot = atomicAdd(&ints[sim.o_color_fill + c.color], 1u) - size;
        st(deep_list() + start + slot, k);
    }
}

// The deep contacts' scratch: the incidence lists' unsorted copy (o_inc_tmp, 2 x
// cap_contacts words) is dead once incidence_rank has sorted it, until the next step's
// incidence_fill rewrites it. Its first half takes the deep contacts at the positions of
// `order` (deep_list), its second half the colors that hold some (deep_runs_at). The
// per-color fill counters (o_color_fill, cleared at the next step's start) carry the count.
fn deep_list() -> u32 { return sim.o_inc_tmp; }
fn deep_runs_at() -> u32 { return sim.o_inc_tmp + sim.cap_contacts; }

var<workgroup> deep_runs: u32;
var<workgroup> deep_sweeps_run: u32;

// Part 2, in one workgroup (one dispatch whatever sim.deep_sweeps and the colors): add the
// step's count to the sum since the last reduction (u32 bits); list the colors holding deep
// contacts; then sim.deep_sweeps times, each such color's deep contacts updated once more,
// unrelaxed, the colors in increasing order with a barrier between two: the result of the
// color-ordered sequential sweep of the deep contacts. Contacts of one color share no
// movable body, so the threads of a color never write the same velocity and their updates
// commute (the order within a color does not matter); the barrier hands the next color the
// velocities this one wrote. The selection does not change during the updates, as on the
// CPU. Barriers need uniform control flow: the number of colors to sweep and of sweeps
// reach every thread through workgroupUniformLoad. llvmpipe (lavapipe) ends the loops of
// an invocation after 65,535 iterations in all (see scan.wgsl) and goes on silently; with
// sim.deep_budget > 0 (the host sets it on a software adapter) thread 0, which loops the
// most, counts what the sweeps will cost it (each loop's iterations plus one for its exit
// test, with a margin in the budget) and runs only as many sweeps as fit, adding the
// sweeps left out to the second word of f_deep.
@compute @workgroup_size(WG)
fn deep_updates(@builtin(local_invocation_index) t: u32) {
    if t == 0u {
        let count = ld(sim.o_status + ST_DEEP);
        floats[sim.f_deep] = bitcast<f32>(bitcast<u32>(floats[sim.f_deep]) + count);
        var runs = 0u;
        var sweeps = sim.deep_sweeps;
        if count > 0u {
            let n_colors = min(ld(sim.o_status + ST_COLORS), sim.max_colors);
            var per_sweep = 1u;
            for (var col = 0u; col < n_colors; col++) {
                let size = ld(sim.o_color_count + col + 1u) - ld(sim.o_color_count + col);
                let deep = ld(sim.o_color_fill + col) - size;
                st(sim.o_color_fill + col, deep);
                if deep > 0u {
                    st(deep_runs_at() + runs, col);
                    runs++;
                    per_sweep += 2u + (deep + WG - 1u) / WG;
                }
            }
            let listing = n_colors + 1u;
            if sim.deep_budget > 0u {
                let fit = select(0u, (sim.deep_budget - listing) / per_sweep, sim.deep_budget > listing);
                if fit < sweeps {
                    let cut = bitcast<u32>(floats[sim.f_deep + 1u]) + sweeps - fit;
                    floats[sim.f_deep + 1u] = bitcast<f32>(cut);
                    sweeps = fit;
                }
            }
        }
        deep_runs = runs;
        deep_sweeps_run = sweeps;
    }
    // The counts and the list of colors, written by thread 0, for every thread.
    storageBarrier();
    let n_runs = workgroupUniformLoad(&deep_runs);
    let n_sweeps = workgroupUniformLoad(&deep_sweeps_run);
    // A step without deep contacts ends here.
    if n_runs == 0u { return; }
    for (var s = 0u; s < n_sweeps; s++) {
        for (var run = 0u; run < n_runs; run++) {
            let col = ld(deep_runs_at() + run);
            let lo = ld(sim.o_color_count + col);
            let hi = lo + ld(sim.o_color_fill + col);
            for (var i = lo + t; i < hi; i += WG) {
                _ = gs_update(ld(deep_list() + i), 1.0);
            }
            storageBarrier();
        }
    }
}

// Entry e of the solve's dispatch arguments: x workgroups (y = z = 1).
fn set_disp(e: u32, x: u32) {
    st(sim.o_disp + 3u * e, x);
    st(sim.o_disp + 3u * e + 1u, 1u);
    st(sim.o_disp + 3u * e + 2u, 1u);
}

// After the coloring: the dispatch arguments of the solve (buffers::disp), which the host
// copies into the indirect buffer, so that each color's sweep covers its members without
// the host knowing the colors' sizes. Colors past the last one get no workgroup (the host
// records as many colors as the last steps needed, with a margin). Opens the solve: the
// iteration count and the convergence flags start from zero (the status words are
// cleared at the step's start).
@compute @workgroup_size(WG)
fn solve_args(@builtin(local_invocation_index) t: u32) {
    let n = n_contacts();
    let live = n > 0u;
    let n_colors = min(ld(sim.o_status + ST_COLORS), sim.max_colors);
    if t == 0u {
        // The sweep order of the colors: those of more than WG contacts in color order,
        // each a dispatch, then the others in color order for sweep_tail. Empty colors
        // are left out.
        var big = 0u;
        var nonempty = 0u;
        for (var c = 0u; c < n_colors; c++) {
            let size = ld(sim.o_color_count + c + 1u) - ld(sim.o_color_count + c);
            if size > WG {
                st(sim.o_color_map + big, c);
                big++;
            }
            nonempty += u32(size > 0u);
        }
        var tail = 0u;
        for (var c = 0u; c < n_colors; c++) {
            let size = ld(sim.o_color_count + c + 1u) - ld(sim.o_color_count + c);
            if size > 0u && size <= WG {
                st(sim.o_color_map + big + tail, c);
                tail++;
            }
        }
        st(sim.o_status + ST_BIG, select(0u, big, live));
        st(sim.o_status + ST_TAIL, select(0u, tail, live));
        st(sim.o_status + ST_NONEMPTY, nonempty);
    }
    storageBarrier();
    let big = ld(sim.o_status + ST_BIG);
    for (var c = t; c < sim.max_colors; c += WG) {
        var x = 0u;
        if c < big {
            let col = ld(sim.o_color_map + c);
            let size = ld(sim.o_color_count + col + 1u) - ld(sim.o_color_count + col);
            x = (size + WG - 1u) / WG;
        }
        set_disp(DISP_COLOR0 + c, x);
    }
    if t == 0u {
        let groups = (n + WG - 1u) / WG;
        set_disp(DISP_CONTACTS, groups);
        set_disp(DISP_LIVE_CONTACTS, select(0u, groups, live));
        set_disp(DISP_LIVE_BODIES, select(0u, (sim.n_bodies + WG - 1u) / WG, live));
        set_disp(DISP_LIVE_ONE, select(0u, 1u, live));
        st(sim.o_status + ST_LIVE, u32(live));
        st(sim.o_status + ST_CONVERGED, u32(!live));
    }
}

// Whether x is finite, read from its bits: WGSL lets a compiler assume that no float is
// infinite or NaN, so a comparison could be folded away.
fn finite_bits(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

var<workgroup> red_a: array<f32, 256>;
var<workgroup> red_b: array<f32, 256>;
var<workgroup> conv_live: u32;

// The convergence test closing a block of iterations (CPU twin: solver::convergence):
// args.a is the block's iterations, args.b 1 when the velocity test applies to it, args.c
// the bits of the relaxation its change is divided by. Sums sum |dR|^2 and sum |R|^2 of the
// block's last iteration (to floats[f_conv + FC_D2], [f_conv + FC_R2]) and adds the block
// to the step's iterations. When the relative change meets sim.tol, the velocity change
// (velocity_change, before this) meets sim.velocity_tol, the cap is reached or a sum is
// not finite, it ends the solve: the solve's dispatch arguments go to zero workgroups, so
// the blocks recorded after this one dispatch nothing, and this kernel returns at once.
@compute @workgroup_size(256)
fn conv_check(@builtin(local_invocation_index) t: u32) {
    if t == 0u { conv_live = ld(sim.o_status + ST_LIVE); }
    if workgroupUniformLoad(&conv_live) == 0u { return; }
    var a = 0.0;
    var b = 0.0;
    let n = n_contacts();
    for (var k = t; k < n; k += 256u) {
        a += floats[sim.f_d2 + k];
        b += floats[sim.f_r2 + k];
    }
    red_a[t] = a;
    red_b[t] = b;
    workgroupBarrier();
    for (var off = 128u; off > 0u; off >>= 1u) {
        if t < off {
            red_a[t] += red_a[t + off];
            red_b[t] += red_b[t + off];
        }
        workgroupBarrier();
    }
    if t == 0u {
        let d2 = red_a[0];
        let r2 = red_b[0];
        floats[sim.f_conv + FC_D2] = d2;
        floats[sim.f_conv + FC_R2] = r2;
        let done = ld(sim.o_status + ST_ITERS) + args.a;
        st(sim.o_status + ST_ITERS, done);
        let w = bitcast<f32>(args.c);
        let bad = !finite_bits(d2) || !finite_bits(r2);
        // As solver::convergence::relative_change: 0 without change, infinite (the
        // largest float here) when only the change is nonzero.
        var residual = 0.0;
        if d2 != 0.0 {
            residual = 3.4e38;
            if r2 > 0.0 { residual = sqrt(d2 / r2) / w; }
        }
        var met = residual <= sim.tol;
        if args.b == 1u && sim.velocity_tol > 0.0 && floats[sim.f_conv + FC_DV] / w <= sim.velocity_tol {
            met = true;
        }
        st(sim.o_status + ST_RESIDUAL, bitcast<u32>(residual));
        if bad || met || done >= sim.max_iter {
            st(sim.o_status + ST_LIVE, 0u);
            st(sim.o_status + ST_CONVERGED, u32(met && !bad));
            st(sim.o_status + ST_BAD, u32(bad));
            for (var e = DISP_LIVE_CONTACTS; e < DISP_COLOR0 + sim.max_colors; e++) {
                st(sim.o_disp + 3u * e, 0u);
            }
        }
    }
}

