//! Entry point: everything happens in [`mentalsim::cli::main`].

/// mimalloc, not glibc's malloc: the service allocates small, short-lived values per SPARQL row
/// and per simulation step on many threads, where glibc's malloc and free cost 12-16% of a
/// query's CPU (docs/benchmarks.md, `bench knowledge`).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    // No transparent huge pages for this process. mimalloc asks for them on its arenas, and
    // where the kernel compacts memory to find one (`defrag` = `madvise`, Debian's default)
    // the allocating thread stalls: 20 plans at once spent 3–6 s of system time, against
    // 0.4–0.8 s without, and their p95 latency was 1.7–2.1 s against 1.1–1.3 s
    // (docs/benchmarks.md, `bench fleet`). Where the call is refused nothing else changes.
    #[cfg(target_os = "linux")]
    let _ = nix::sys::prctl::set_thp_disable(true);
    mentalsim::cli::main()
}
