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

// Exclusive prefix sum of ints[args.a .. args.a + args.b], the total written at
// ints[args.a + args.b]. One workgroup walks the region in blocks of 256 with a carry: the
// regions scanned (cells, disks, bodies) are a few times the disk count, so one workgroup
// keeps the pass simple and deterministic at a cost far below the solver's. Its limit:
// llvmpipe (lavapipe) ends every loop of an invocation after 65,535 iterations in all, and
// a block costs 9 (the walk and the 8 steps of the tree), so a region may hold up to
// 7,281 blocks (1.86 million words): the cell region of 466,000 disks, more than the
// contact buffer of lavapipe's 128 MiB binding allows (300,000 disks).
@compute @workgroup_size(256)
fn scan(@builtin(local_invocation_index) t: u32) {
    let base = args.a;
    let n = args.b;
    var carry = 0u;
    for (var start = 0u; start < n; start += 256u) {
        let k = start + t;
        var v = 0u;
        if k < n { v = ld(base + k); }
        scan_tmp[t] = v;
        workgroupBarrier();
        // Hillis-Steele inclusive scan in shared memory.
        for (var off = 1u; off < 256u; off <<= 1u) {
            var add = 0u;
            if t >= off { add = scan_tmp[t - off]; }
            workgroupBarrier();
            scan_tmp[t] += add;
            workgroupBarrier();
        }
        if k < n { st(base + k, carry + scan_tmp[t] - v); }
        carry += scan_tmp[255];
        workgroupBarrier();
    }
    if t == 0u { st(base + n, carry); }
}
