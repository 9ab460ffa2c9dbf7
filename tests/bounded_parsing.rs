//! Programs are parsed in the API process when they are uploaded (and when a job brings
//! one inline). A parse holds several times its text, so the text parsed at once is
//! bounded by one largest program (`--max-program-bytes`): concurrent uploads of large
//! programs take turns instead of adding their parses up.

mod common;

use std::time::Instant;

use common::*;

/// About `mb` MB of straight moves: every line a block with words to keep.
fn dense_program(mb: usize) -> String {
    let mut out = String::from("G21 G90 G17\n");
    let mut i = 0u64;
    while out.len() < mb << 20 {
        out.push_str(&format!(
            "G1 X{}.{} Y{}.25 F500\n",
            i % 97,
            i % 10,
            (i / 97) % 89
        ));
        i += 1;
    }
    out.push_str("M30\n");
    out
}

/// Four uploads at once of a program as large as the server takes: the server's peak
/// grows by about one parse, not four (before, each upload parsed as it arrived).
#[tokio::test]
async fn concurrent_uploads_of_large_programs_parse_in_turn() {
    let dir = tempfile::tempdir().unwrap();
    let program = dense_program(6);
    let limit = (program.len() + 1024).to_string();
    let s = std::sync::Arc::new(Server::start(
        &dir.path().join("t.db"),
        &["--workers", "0", "--max-program-bytes", &limit],
    ));
    let pid = s.child.id();
    let c = client();

    reset_peak_rss(pid);
    let rss = proc_kb(pid, "VmRSS");
    post_program(&c, &s, "one.nc", program.clone()).await;
    let one_mb = proc_kb(pid, "VmHWM").saturating_sub(rss) as f64 / 1024.0;

    reset_peak_rss(pid);
    let rss = proc_kb(pid, "VmRSS");
    let clock = Instant::now();
    let uploads: Vec<_> = (0..4)
        .map(|k| {
            let (c, s, p) = (c.clone(), s.clone(), program.clone());
            tokio::spawn(async move { post_program(&c, &s, &format!("p{k}.nc"), p).await })
        })
        .collect();
    for u in uploads {
        u.await.unwrap();
    }
    let four_mb = proc_kb(pid, "VmHWM").saturating_sub(rss) as f64 / 1024.0;
    println!(
        "a {} MB program: one upload peak +{one_mb:.1} MB; four at once +{four_mb:.1} MB in {:.1} s",
        program.len() >> 20,
        clock.elapsed().as_secs_f64()
    );
    assert!(
        one_mb > 20.0,
        "a parse this large should show in the peak: +{one_mb:.1} MB"
    );
    assert!(
        four_mb < 2.0 * one_mb + 16.0,
        "four concurrent uploads took the peak +{four_mb:.1} MB, one +{one_mb:.1} MB"
    );
}
