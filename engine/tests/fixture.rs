//! Fixtures: clamps and vices checked against the whole tool on every move. Expected
//! contacts are worked out by hand from the boxes, cylinders and ramps below.

mod common;

use std::sync::Arc;

use millsim_engine::geometry::fixture::{ToolEnvelope, ToolPart};
use millsim_engine::geometry::{Fixture, FixtureSpec, Mesh, Segment, MAX_FIXTURE_BODIES};
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::pipeline::simulate;
use millsim_engine::tool::{HolderSegment, Tool};
use serde_json::{json, Value};

/// Flat Ø10 mm, flutes 20 mm, stick-out 40 mm (shank Ø10), and a Ø32 holder 40 mm long
/// above it: the holder spans 40..80 mm above the tip.
fn tool() -> Tool {
    let mut t = Tool::flat(10.0, 3);
    t.flute_length = 20.0;
    t.stick_out = Some(40.0);
    t.holder = vec![HolderSegment {
        length: 40.0,
        bottom_diameter: 32.0,
        top_diameter: 32.0,
    }];
    t
}

fn fixture(doc: Value) -> Fixture {
    FixtureSpec::from_json(&doc, "path")
        .unwrap()
        .build("path", |r| Err(format!("no mesh {r}")))
        .unwrap()
}

fn clamp(min: [f64; 3], max: [f64; 3]) -> Fixture {
    fixture(json!({"bodies":[{"name":"clamp 1","kind":"block","min":min,"max":max}]}))
}

fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
}

#[test]
fn a_rapid_through_a_clamp_is_caught_where_the_flutes_first_touch_it() {
    let f = clamp([30.0, 10.0, 0.0], [40.0, 30.0, 15.0]);
    let env = ToolEnvelope::new(&tool());
    // Along x at y 20, the tip at z 5: the flutes' leading edge (x + 5) reaches x 30.
    let c = f
        .first_contact(
            &env,
            &Segment::rapid(3, [-20.0, 20.0, 5.0], [80.0, 20.0, 5.0]),
        )
        .unwrap()
        .expect("the rapid crosses the clamp");
    assert_eq!(c.name, "clamp 1");
    assert_eq!(c.part, ToolPart::Flutes);
    assert!(close(c.tip, [25.0, 20.0, 5.0], 1e-6), "{:?}", c.tip);
    assert!((c.u - 0.45).abs() < 1e-8, "{}", c.u);
    // The point is on the clamp's face x = 30, where the flutes are (z 5..15 of the clamp).
    assert!((c.point[0] - 30.0).abs() < 1e-6, "{:?}", c.point);
    assert!((c.point[1] - 20.0).abs() < 1e-6, "{:?}", c.point);
    assert!(
        (5.0 - 1e-6..=15.0 + 1e-6).contains(&c.point[2]),
        "{:?}",
        c.point
    );
    // The same rapid 0.5 mm above the clamp's top meets nothing below the holder... but
    // the holder is above too: nothing at all.
    assert_eq!(
        f.first_contact(
            &env,
            &Segment::rapid(3, [-20.0, 20.0, 15.5], [80.0, 20.0, 15.5])
        )
        .unwrap(),
        None
    );
}

#[test]
fn a_feed_beside_a_clamp_with_1_mm_clearance_is_not_flagged_and_0_01_mm_into_it_is() {
    let f = clamp([30.0, 10.0, -20.0], [40.0, 30.0, 15.0]);
    let env = ToolEnvelope::new(&tool());
    let beside = Segment::linear(7, [24.0, -10.0, -2.0], [24.0, 50.0, -2.0], 800.0, 8000.0);
    assert_eq!(f.first_contact(&env, &beside).unwrap(), None);
    let into = Segment::linear(7, [25.01, -10.0, -2.0], [25.01, 50.0, -2.0], 800.0, 8000.0);
    let c = f
        .first_contact(&env, &into)
        .unwrap()
        .expect("0.01 mm into the clamp");
    // The edge at x 30.01 meets the face y = 10 when the tip is a chord's half-width
    // short of it: √(5² − 4.99²).
    let half = (25.0f64 - 4.99 * 4.99).sqrt();
    assert!((c.tip[1] - (10.0 - half)).abs() < 1e-6, "{:?}", c.tip);
    assert_eq!(c.part, ToolPart::Flutes);
}

#[test]
fn the_holder_meets_a_tall_clamp_while_the_flutes_pass_clear() {
    // Tall clamp: up to z 45. The flutes at x 20 clear its face x 30 by 5 mm; the Ø32
    // holder (40..80 mm above the tip at z −2: z 38..78) reaches x 36.
    let f = clamp([30.0, 10.0, -20.0], [40.0, 30.0, 45.0]);
    let path = Segment::linear(9, [20.0, -30.0, -2.0], [20.0, 50.0, -2.0], 800.0, 8000.0);
    let c = f
        .first_contact(&ToolEnvelope::new(&tool()), &path)
        .unwrap()
        .expect("the holder meets the clamp");
    assert_eq!(c.part, ToolPart::Holder);
    // The holder's circle (radius 16 about x 20) crosses x 30 ±√(16² − 10²) from its
    // centre in y: it reaches the face y 10 with the tip at y 10 − √156.
    assert!(
        (c.tip[1] - (10.0 - 156f64.sqrt())).abs() < 1e-6,
        "{:?}",
        c.tip
    );
    assert!(
        close(c.point, [30.0, 10.0, c.point[2]], 1e-6),
        "{:?}",
        c.point
    );
    assert!(
        (38.0 - 1e-6..=45.0 + 1e-6).contains(&c.point[2]),
        "{:?}",
        c.point
    );
    // Without the holder the same move is clear: it was the holder, not the flutes.
    let mut bare = tool();
    bare.holder.clear();
    assert_eq!(
        f.first_contact(&ToolEnvelope::new(&bare), &path).unwrap(),
        None
    );
}

#[test]
fn an_arc_around_a_round_clamp_is_checked_on_its_true_path() {
    // A Ø10 round clamp at the origin; the Ø10 tool circles it: the tip on a radius of
    // 10.01 clears it by 0.01 mm, on 9.99 it cuts 0.01 mm into it.
    let f = fixture(json!({"bodies":[{"name":"post","kind":"cylinder",
        "base_center":[0.0,0.0,-10.0],"radius":5.0,"height":20.0}]}));
    let env = ToolEnvelope::new(&tool());
    let circle = |r: f64| {
        Segment::arc(
            4,
            [r, 0.0, 0.0],
            [r, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            false,
            600.0,
            8000.0,
        )
    };
    assert_eq!(f.first_contact(&env, &circle(10.01)).unwrap(), None);
    let c = f
        .first_contact(&env, &circle(9.99))
        .unwrap()
        .expect("into the post");
    assert_eq!(c.name, "post");
    // It touches from the start: the point is on the post's side facing the tool.
    assert!(c.u < 1e-9, "{}", c.u);
    assert!((c.point[0] - 5.0).abs() < 1e-3, "{:?}", c.point);
}

/// An ASCII STL of a ramp: x 30..40, y 10..30, the top rising from z 0 at x 30 to z 10 at
/// x 40 (a wedge: bottom, back wall at x 40, sloped top, two triangular sides).
fn ramp_stl() -> String {
    let (a, b, c, d) = (
        [30.0, 10.0, 0.0],
        [40.0, 10.0, 0.0],
        [40.0, 30.0, 0.0],
        [30.0, 30.0, 0.0],
    );
    let (e, g) = ([40.0, 10.0, 10.0], [40.0, 30.0, 10.0]);
    let tris: [[[f64; 3]; 3]; 8] = [
        [a, c, b],
        [a, d, c], // bottom, facing down
        [b, c, g],
        [b, g, e], // back wall x 40, facing +x
        [a, e, g],
        [a, g, d], // sloped top
        [a, b, e], // side y 10, facing −y
        [d, g, c], // side y 30, facing +y
    ];
    let mut s = String::from("solid ramp\n");
    for t in tris {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for v in t {
            s.push_str(&format!("vertex {} {} {}\n", v[0], v[1], v[2]));
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid ramp\n");
    s
}

#[test]
fn an_stl_body_is_met_on_its_sloped_face() {
    let doc = json!({"bodies":[{"name":"ramp","kind":"stl","path":"ramp.stl"}]});
    let f = FixtureSpec::from_json(&doc, "path")
        .unwrap()
        .build("path", |r| {
            assert_eq!(r, "ramp.stl");
            Mesh::from_stl_bytes(ramp_stl().as_bytes()).map_err(|e| e.to_string())
        })
        .unwrap();
    let env = ToolEnvelope::new(&tool());
    // The tip at z 5 along x: the slope is at height 5 at x 35, so the flutes' bottom edge
    // (x + 5) meets it with the tip at x 30.
    let c = f
        .first_contact(
            &env,
            &Segment::rapid(2, [0.0, 20.0, 5.0], [60.0, 20.0, 5.0]),
        )
        .unwrap()
        .expect("the rapid meets the ramp");
    assert_eq!(c.name, "ramp");
    assert!(close(c.tip, [30.0, 20.0, 5.0], 1e-6), "{:?}", c.tip);
    // The point is taken 0.1 µm of path before the contact: within 1e-4 mm of it.
    assert!(
        (c.point[0] - 35.0).abs() < 1e-4 && (c.point[2] - 5.0).abs() < 1e-4,
        "{:?}",
        c.point
    );
    // 0.5 mm above the ramp's top edge: clear.
    assert_eq!(
        f.first_contact(
            &env,
            &Segment::rapid(2, [0.0, 20.0, 10.5], [60.0, 20.0, 10.5])
        )
        .unwrap(),
        None
    );
    // A tool short enough to sit wholly inside the wedge crosses none of its triangles but
    // is inside it.
    let mut stub = Tool::flat(2.0, 2);
    stub.flute_length = 1.0;
    stub.stick_out = Some(1.0);
    let c = f
        .first_contact(
            &ToolEnvelope::new(&stub),
            &Segment::rapid(2, [38.0, 20.0, 1.0], [38.0, 21.0, 1.0]),
        )
        .unwrap()
        .expect("inside the ramp");
    assert!(c.u < 1e-9);
}

#[test]
fn bodies_are_bounded_and_every_error_names_its_field() {
    let block = |i: usize| json!({"kind":"block","min":[i as f64,0,0],"max":[i as f64 + 1.0,1,1]});
    let many: Vec<Value> = (0..MAX_FIXTURE_BODIES).map(block).collect();
    let f = fixture(json!({ "bodies": many }));
    assert_eq!(f.len(), MAX_FIXTURE_BODIES);
    assert_eq!(f.names().nth(63), Some("body 64"));
    let too_many: Vec<Value> = (0..=MAX_FIXTURE_BODIES).map(block).collect();
    let e = FixtureSpec::from_json(&json!({ "bodies": too_many }), "path").unwrap_err();
    assert_eq!(e.field, "bodies");
    assert!(
        e.message.contains("65 bodies") && e.message.contains("64"),
        "{e}"
    );

    let err = |doc: Value| FixtureSpec::from_json(&doc, "input").unwrap_err();
    let e = err(json!({"bodies":[block(0), block(1),
        {"kind":"block","min":[0,0,5],"max":[1,1,5]}]}));
    assert_eq!(e.field, "bodies[2].max");
    assert!(e.message.contains("z must exceed"), "{e}");
    assert_eq!(err(json!({"bodies":[]})).field, "bodies");
    assert_eq!(
        err(json!({"bodies":[{"kind":"cylinder","base_center":[0,0,0],"radius":-1,"height":3}]}))
            .field,
        "bodies[0].radius"
    );
    assert_eq!(
        err(json!({"bodies":[{"kind":"sphere"}]})).field,
        "bodies[0].kind"
    );
    assert_eq!(
        err(json!({"bodies":[{"kind":"stl"}]})).field,
        "bodies[0].input"
    );
    assert_eq!(
        err(json!({"bodies":[{"kind":"block","min":[0,0,0],"max":[1,1,1],"colour":"red"}]})).field,
        "bodies[0].colour"
    );
    assert_eq!(
        err(
            json!({"bodies":[{"name":"a","kind":"block","min":[0,0,0],"max":[1,1,1]},
            {"name":"a","kind":"block","min":[2,0,0],"max":[3,1,1]}]})
        )
        .field,
        "bodies[1].name"
    );
    assert_eq!(
        err(json!({"bodies":[{"kind":"block","min":[0,"x",0],"max":[1,1,1]}]})).field,
        "bodies[0].min"
    );
    // A mesh that cannot be had is the body's error.
    let e = FixtureSpec::from_json(
        &json!({"bodies":[block(0), {"kind":"stl","path":"vice.stl"}]}),
        "path",
    )
    .unwrap()
    .build("path", |_| Err("no such file".into()))
    .unwrap_err();
    assert_eq!(e.field, "bodies[1].path");
    assert!(e.message.contains("vice.stl: no such file"), "{e}");
}

/// The pipeline: a rapid through a clamp beside the stock is flagged at its line, with
/// the body named in the row and the point in the summary; the feed pass beside the clamp
/// with 1 mm to spare is not.
#[test]
fn a_simulation_flags_the_rapid_through_the_clamp_at_its_line() {
    // Stock x 0..100, y −20..20, top z 0; the clamp beside it at y 22..32, up to z 8.
    let program = "G21 G90 G17\nS10000 M3\nG0 X-10 Y27 Z5\nG0 X120\nG0 Z20\nG0 X-10 Y16\n\
        G1 Z-2 F600\nG1 X120 F1000\nG0 Z20\nM30\n";
    let mut spec = common::simulate::block_spec(program, tool(), 0.5);
    spec.fixture = Some(Arc::new(fixture(json!({"bodies":[
        {"name":"clamp 1","kind":"block","min":[40,22,-10],"max":[50,32,8]},
        {"name":"clamp 2","kind":"block","min":[40,-32,-10],"max":[50,-22,8]}]}))));
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let flagged: Vec<&_> = out.rows.iter().filter(|r| r.fixture_contact).collect();
    assert_eq!(flagged.len(), 1, "{:?}", out.summary.fixture);
    let row = flagged[0];
    assert_eq!((row.line, row.kind), (4, "rapid"));
    assert_eq!(row.fixture_body.as_deref(), Some("clamp 1"));
    assert!(
        row.flags.split('|').any(|f| f == "fixture_contact"),
        "{}",
        row.flags
    );
    // The feed pass along y 16 (edge at y 21, the clamp from y 22) is clear.
    let pass = out.rows.iter().find(|r| r.line == 8).unwrap();
    assert!(!pass.fixture_contact && pass.removed_volume > 0.0);

    let fx = out.summary.fixture.as_ref().expect("the fixture's summary");
    assert_eq!(fx.bodies, ["clamp 1", "clamp 2"]);
    assert_eq!(fx.collision_moves, 1);
    let c = &fx.collisions[0];
    assert_eq!(
        (c.body.as_str(), c.line, c.kind, c.part),
        ("clamp 1", 4, "rapid", ToolPart::Flutes)
    );
    // The flutes' edge (x + 5) reaches the clamp's face x 40 at the tip's x 35.
    assert!(close(c.tip, [35.0, 27.0, 5.0], 1e-6), "{:?}", c.tip);
    assert!((c.point[0] - 40.0).abs() < 1e-6, "{:?}", c.point);
    assert!(out
        .summary
        .collisions
        .iter()
        .any(|k| k.kind == "fixture_contact" && k.line == 4));
    assert!(
        out.summary
            .warnings
            .iter()
            .any(|w| w.contains("line 4") && w.contains("clamp 1")),
        "{:?}",
        out.summary.warnings
    );
    // Every row names the fixture_body column (null where the move met nothing).
    let json = millsim_engine::pipeline::RowJson::new(&out.rows);
    for r in &out.rows {
        let v: Value = serde_json::from_str(&json.to_json(r)).unwrap();
        assert!(v.get("fixture_body").is_some(), "{v}");
    }
}

/// The machine's start counts: a first rapid from the start position through a clamp
/// that stands over program zero is flagged.
#[test]
fn the_rapid_from_where_the_program_starts_is_checked() {
    // The generic machine starts over X0 Y0 above the stock; a clamp on the way to X50.
    let program = "G21 G90 G17\nS10000 M3\nG0 X50 Y0\nG0 Z-2\nM30\n";
    let mut spec = common::simulate::block_spec(program, tool(), 0.5);
    let top = spec.machine.clearance_mm;
    spec.fixture = Some(Arc::new(clamp([20.0, -5.0, 0.0], [25.0, 5.0, top + 1.0])));
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let c = &out.summary.fixture.as_ref().unwrap().collisions;
    assert_eq!(c.len(), 1, "{c:?}");
    assert_eq!(c[0].line, 3);
    assert!(close(c[0].tip, [15.0, 0.0, top], 1e-6), "{:?}", c[0].tip);
}
