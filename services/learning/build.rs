//! Embeds libtorch's directory as an rpath in this crate's test and example binaries, and
//! passes it on to dependent crates, so nothing needs LD_LIBRARY_PATH at run time. Without the
//! `train` feature there is no libtorch and nothing to do.

fn main() {
    println!("cargo:rerun-if-env-changed=DEP_TCH_LIBTORCH_LIB");
    if std::env::var_os("CARGO_FEATURE_TRAIN").is_none() {
        return;
    }
    if let Ok(dir) = std::env::var("DEP_TCH_LIBTORCH_LIB") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
        println!("cargo:libtorch_lib={dir}");
    }
}
