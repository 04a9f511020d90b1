//! `mentalsim bench plan-load` against a real service started by the test: plans answered
//! under concurrent clients, with the service's and the load generator's CPU time per plan.

use super::mentalsim;
use super::served::Serve;

#[test]
fn plan_load_measures_a_running_service_and_its_cpu_time_per_plan() {
    let mut service = Serve::new().check_ready().start();
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("plan-load.json");
    let out = mentalsim()
        .args([
            "bench",
            "plan-load",
            "--clients",
            "2",
            "--seconds",
            "2",
            "--url",
        ])
        .arg(&service.url)
        .args(["--token", &service.token, "--server-pid"])
        .arg(service.pid().to_string())
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert!(report["requests"].as_u64().unwrap() >= 2, "{report}");
    assert_eq!(report["errors"], 0, "{report}");
    assert!(report["p50_ms"].as_f64().unwrap() > 0.0, "{report}");
    // Planning takes the service's CPU, not nothing and not more than the whole machine's.
    let server = report["server_cpu_ms_per_plan"].as_f64().unwrap();
    let cores = std::thread::available_parallelism().unwrap().get() as f64;
    let wall_per_plan = 2000.0 / report["requests"].as_f64().unwrap();
    assert!(
        server > 0.0 && server < 1.5 * cores * wall_per_plan,
        "{report}"
    );
    assert!(
        report["client_cpu_ms_per_plan"].as_f64().unwrap() >= 0.0,
        "{report}"
    );

    // A process that is not there is named, not measured as nothing.
    let out = mentalsim()
        .args([
            "bench",
            "plan-load",
            "--clients",
            "1",
            "--seconds",
            "1",
            "--url",
        ])
        .arg(&service.url)
        .args(["--token", &service.token, "--server-pid", "4194305"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("--server-pid 4194305"), "{stderr}");

    service.kill_now();
}
