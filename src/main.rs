fn main() {
    // Mesa's Vulkan drivers probe Wayland while wgpu lists adapters and, on a headless
    // machine without XDG_RUNTIME_DIR, print "error: XDG_RUNTIME_DIR is invalid or not set"
    // twice per run: a misleading "error" in every `cdlab biaxial` output. cdlab opens no
    // window, so pointing the variable at the temporary directory only silences the probe.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // SAFETY: no other thread exists yet, so nothing reads the environment concurrently.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    std::process::exit(cdlab::cli::main());
}
