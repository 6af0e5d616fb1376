/// Large samples' steps walk tens of megabytes; huge pages make them faster where the kernel
/// gives them only on request (src/hugepages.rs).
#[global_allocator]
static ALLOCATOR: cdlab::hugepages::HugePages = cdlab::hugepages::HugePages;

fn main() {
    // Mesa's Vulkan drivers probe Wayland while wgpu lists adapters and, on a headless
    // machine without XDG_RUNTIME_DIR, print "error: XDG_RUNTIME_DIR is invalid or not set"
    // twice per run: a misleading "error" in every `cdlab biaxial` output. cdlab opens no
    // window, so pointing the variable at the temporary directory only silences the probe.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // SAFETY: no other thread exists yet, so nothing reads the environment concurrently.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    // Rust ignores SIGPIPE, so printing into a closed pipe (`cdlab report DIR | head`) made
    // println! panic; the default action ends the process quietly, as for other tools.
    #[cfg(unix)]
    // SAFETY: called before any other thread exists; SIG_DFL is a valid disposition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    std::process::exit(cdlab::cli::main());
}
