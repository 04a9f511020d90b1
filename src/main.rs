//! Entry point: everything happens in [`mentalsim::cli::main`].

fn main() -> std::process::ExitCode {
    mentalsim::cli::main()
}
