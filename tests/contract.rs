//! The contract and the router agree: every route the server has is in openapi.yaml
//! with its method, and every operation in openapi.yaml is served.

mod common;

use std::collections::BTreeSet;

use common::*;

/// (METHOD, path) pairs of openapi.yaml's `paths`, read from its block layout: paths at
/// two spaces of indent, operations at four.
fn contract_operations() -> BTreeSet<(String, String)> {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/openapi.yaml")).unwrap();
    let mut ops = BTreeSet::new();
    let mut in_paths = false;
    let mut path = String::new();
    for line in text.lines() {
        if !line.starts_with(' ') {
            in_paths = line.starts_with("paths:");
            continue;
        }
        if !in_paths {
            continue;
        }
        let indent = line.len() - line.trim_start().len();
        let key = line.trim().trim_end_matches(':').trim_matches('"');
        if indent == 2 {
            path = key.to_string();
        } else if indent == 4 && ["get", "post", "put", "patch", "delete"].contains(&key) {
            ops.insert((key.to_uppercase(), path.clone()));
        }
    }
    ops
}

fn router_operations() -> BTreeSet<(String, String)> {
    let out = std::process::Command::new(BIN)
        .arg("routes")
        .output()
        .unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let (m, p) = l.split_once(' ').unwrap();
            (m.to_string(), p.to_string())
        })
        .collect()
}

#[test]
fn every_route_is_in_the_contract_and_back() {
    let contract = contract_operations();
    let router = router_operations();
    assert!(router.len() > 30, "route table looks empty: {router:?}");
    let missing: Vec<_> = router.difference(&contract).collect();
    let extra: Vec<_> = contract.difference(&router).collect();
    assert!(
        missing.is_empty(),
        "routes served but not in openapi.yaml: {missing:?}"
    );
    assert!(
        extra.is_empty(),
        "operations in openapi.yaml but not in the route table: {extra:?}"
    );
}

#[tokio::test]
async fn the_live_router_serves_every_route_of_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    for (method, path) in router_operations() {
        let url = s.url(&path.replace("{id}", "00000000-0000-0000-0000-000000000000"));
        let req = c.request(method.parse().unwrap(), &url);
        let req = if method == "POST" {
            req.header("content-type", "application/json").body("{}")
        } else {
            req
        };
        let res = req.send().await.unwrap();
        let status = res.status().as_u16();
        let body = res.text().await.unwrap_or_default();
        assert_ne!(status, 405, "{method} {path}: method not routed");
        assert!(
            !body.contains("problems/no-route"),
            "{method} {path}: not routed: {body}"
        );
    }
}
