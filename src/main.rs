//! Entry point: everything happens in [`mentalsim::cli::main`].

/// mimalloc, not glibc's malloc: the service allocates small, short-lived values per SPARQL row
/// and per simulation step on many threads, where glibc's malloc and free cost 12-16% of a
/// query's CPU (docs/benchmarks.md, `bench knowledge`).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    mentalsim::cli::main()
}
