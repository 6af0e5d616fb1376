fn main() {
    std::process::exit(cdlab::cli::main());
}
