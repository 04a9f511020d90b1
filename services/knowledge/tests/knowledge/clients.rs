//! Real clients work unchanged: runs `tests/clients/test_clients.py` (SPARQLWrapper and rdflib's
//! SPARQLStore/SPARQLUpdateStore) against the service on a port of its own, with an engineer's
//! token, using the project venv's Python.

#![allow(clippy::unwrap_used, clippy::print_stdout)] // reason: a test reports and panics

use std::process::Command;

use crate::support::{ENGINEER_TOKEN, Options, engineer_and_robot, spawn_app};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sparqlwrapper_and_rdflib_work_unchanged() {
    let python = crate::support::repository_root().join(".venv/bin/python");
    let script = std::path::PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("tests/clients/test_clients.py");
    let probe = Command::new(&python)
        .args(["-c", "import SPARQLWrapper, rdflib"])
        .output();
    match probe {
        Ok(output) if output.status.success() => {}
        _ => {
            fixtures::missing(format!(
                "{} with SPARQLWrapper and rdflib (scripts/setup installs them)",
                python.display()
            ));
            return;
        }
    }
    let app = spawn_app(Options {
        tokens: engineer_and_robot(),
        ..Options::default()
    })
    .await;
    let url = app.url("");
    let output = tokio::task::spawn_blocking(move || {
        Command::new(&python)
            .arg(&script)
            .env("MENTALSIM_SPARQL_URL", url)
            .env("MENTALSIM_TOKEN", ENGINEER_TOKEN)
            .output()
            .unwrap()
    })
    .await
    .unwrap();
    let report = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    println!("{report}");
    assert!(output.status.success(), "client tests failed:\n{report}");
}
