//! Gives the wire types' test binaries an rpath to libtorch (found by the `learning` crate's
//! build: the training job links it), so they run without LD_LIBRARY_PATH.

fn main() {
    println!("cargo:rerun-if-env-changed=DEP_MENTALSIM_LEARNING_LIBTORCH_LIB");
    if let Ok(dir) = std::env::var("DEP_MENTALSIM_LEARNING_LIBTORCH_LIB") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
}
