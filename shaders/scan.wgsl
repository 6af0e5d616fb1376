// Utility passes shared by several phases (CPU twin: the prefix sums inside
// CellGrid::build and color_contacts): clearing a range of the integer scratch and an
// exclusive prefix sum of a region, in place.

// Zeroes ints[args.a .. args.a + args.b] (the per-step counters, laid out contiguously).
@compute @workgroup_size(WG)
fn clear_ints(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k < args.b { st(args.a + k, 0u); }
}

var<workgroup> scan_tmp: array<u32, 256>;

// Inclusive Hillis-Steele scan of the workgroup's 256 values in shared memory; every thread
// gets its own inclusive sum, and scan_tmp[255] holds the total after the call.
fn scan_256(t: u32, v: u32) -> u32 {
    scan_tmp[t] = v;
    workgroupBarrier();
    for (var off = 1u; off < 256u; off <<= 1u) {
        var add = 0u;
        if t >= off { add = scan_tmp[t - off]; }
        workgroupBarrier();
        scan_tmp[t] += add;
        workgroupBarrier();
    }
    return scan_tmp[t];
}

// The exclusive prefix sum of ints[args.a .. args.a + args.b], in place, with the total at
// ints[args.a + args.b], is three dispatches: scan_blocks, scan_sums, scan_add. The sum is
// of integers, so the result does not depend on how the work is cut. One workgroup walking
// the whole region cost a 50,000-disk step about a millisecond on an H200 (three regions of
// 200 to 400 blocks, each block a chain of barriers: docs/gpu.md, "Measured on hardware");
// cut in blocks of 256, each with its own workgroup, the regions take three launches each.
//
// Part 1, a workgroup per block of 256 words: the block's exclusive prefix sum in place,
// and its total to ints[args.c + block].
@compute @workgroup_size(256)
fn scan_blocks(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
) {
    let k = wg.x * 256u + t;
    var v = 0u;
    if k < args.b { v = ld(args.a + k); }
    let sum = scan_256(t, v);
    if k < args.b { st(args.a + k, sum - v); }
    if t == 255u { st(args.c + wg.x, sum); }
}

// Part 2, one workgroup: the exclusive prefix sum of the args.d block totals, in place, the
// region's total after them (ints[args.c + args.d]). It walks the totals in blocks of 256
// with a carry. Its limit: llvmpipe (lavapipe) ends every loop of an invocation after
// 65,535 iterations in all, and a block costs 9 (the walk and the 8 steps of the tree), so
// it takes up to 7,281 blocks of totals (477 million words), far beyond any region here.
@compute @workgroup_size(256)
fn scan_sums(@builtin(local_invocation_index) t: u32) {
    let base = args.c;
    let n = args.d;
    var carry = 0u;
    for (var start = 0u; start < n; start += 256u) {
        let k = start + t;
        var v = 0u;
        if k < n { v = ld(base + k); }
        let sum = scan_256(t, v);
        if k < n { st(base + k, carry + sum - v); }
        carry += scan_tmp[255];
        workgroupBarrier();
    }
    if t == 0u { st(base + n, carry); }
}

// Part 3, a thread per word: each block's offset added to its words, and the total after
// the region.
@compute @workgroup_size(256)
fn scan_add(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k < args.b { st(args.a + k, ld(args.a + k) + ld(args.c + k / 256u)); }
    if k == 0u { st(args.a + args.b, ld(args.c + args.d)); }
}
