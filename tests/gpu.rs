//! GPU path checks (validation.md, "Cross-checks between the two backends").
//!
//! The shader test needs no adapter. The others run on any adapter wgpu finds
//! (`Backends::all()`; set `WGPU_BACKEND=vulkan` to pick Mesa's lavapipe on a machine
//! without a GPU) and skip with a visible `SKIPPED (no GPU adapter)` line otherwise,
//! unless `CDLAB_REQUIRE_GPU=1` (CI), in which case a missing adapter fails the test.

use std::path::Path;

/// Every WGSL file in `shaders/` parses and validates through naga, composed the way the
/// pipelines compose it (`common.wgsl` first). Iterates the directory, so a new shader is
/// covered without touching this test.
#[test]
fn every_shader_parses_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let common = std::fs::read_to_string(dir.join("common.wgsl")).expect("common.wgsl");
    let mut checked = 0;
    let mut entries: Vec<_> = std::fs::read_dir(&dir)
        .expect("shaders/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .collect();
    entries.sort();
    for path in entries {
        let own = std::fs::read_to_string(&path).expect("shader");
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let source = if name == "common.wgsl" {
            own
        } else {
            cdlab::gpu::compose(&own)
        };
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
        checked += 1;
    }
    assert!(checked >= 8, "only {checked} shaders found");
}
