//! Two `millsim worker` processes on one database never run the same job at once, and
//! together they run every job exactly once.

mod common;

use std::time::Duration;

use common::*;

#[tokio::test]
async fn two_worker_processes_never_share_a_job() {
    if !corpus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("w.db"), &["--workers", "0"]);
    let c = client();
    let program = upload_program(
        &c,
        &s,
        &corpus("gcode/fusion360_2d_pocket_contour_bore_1099.nc"),
    )
    .await;
    let mut ids = Vec::new();
    for _ in 0..40 {
        ids.push(
            submit_interpret(&c, &s, &program).await["id"]
                .as_str()
                .unwrap()
                .to_string(),
        );
    }
    let spawn = || {
        std::process::Command::new(BIN)
            .args([
                "worker",
                "--database",
                &s.db_url,
                "--workers",
                "2",
                "--lease-s",
                "5",
            ])
            .env("RUST_LOG", "warn")
            .spawn()
            .unwrap()
    };
    let (mut w1, mut w2) = (spawn(), spawn());
    let mut per_worker = std::collections::BTreeMap::<String, usize>::new();
    let mut spans = Vec::new();
    for id in &ids {
        let job = wait_job(&c, &s, id, Duration::from_secs(120)).await;
        assert_eq!(job["status"], "succeeded", "{job}");
        assert_eq!(job["attempts"], 1, "a job was claimed twice: {job}");
        let (_, att) = json(
            c.get(s.url(&format!("/v1/jobs/{id}/attempts")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        let items = att["items"].as_array().unwrap();
        assert_eq!(items.len(), 1, "{att}");
        let worker = items[0]["worker"].as_str().unwrap().to_string();
        // Process prefix: host-pid-suffix; the -wN part names the worker inside it.
        let process = worker.rsplit_once("-w").unwrap().0.to_string();
        *per_worker.entry(process).or_default() += 1;
        spans.push((items[0]["started_at"].as_str().unwrap().to_string(), worker));
    }
    common::unsafe_kill(w1.id() as i32, 15);
    common::unsafe_kill(w2.id() as i32, 15);
    assert!(
        w1.wait().unwrap().success(),
        "worker 1 did not shut down cleanly on SIGTERM"
    );
    assert!(
        w2.wait().unwrap().success(),
        "worker 2 did not shut down cleanly on SIGTERM"
    );
    assert_eq!(per_worker.values().sum::<usize>(), 40);
    assert_eq!(
        per_worker.len(),
        2,
        "both processes should have taken work: {per_worker:?}"
    );
}
