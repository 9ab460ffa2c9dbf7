//! Tool libraries: Fusion 360 JSON, LinuxCNC tool tables, CSV, and tools from a program's
//! header comments, each mapped field checked; the example job with its tool from a
//! library and from its own header.

use std::collections::BTreeMap;

use millsim_engine::geometry::StockShape;
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::machine::Machine;
use millsim_engine::nc::InterpretOptions;
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{simulate, SimulateSpec, StockSource};
use millsim_engine::tool::{Tool, ToolShape};
use millsim_engine::tool_library::{tools_from_header, ToolLibrary};

/// A Fusion 360 library in the format its CAM API documents.
const FUSION: &str = r#"{"data":[
 {"type":"flat end mill","unit":"millimeters","description":"6 mm flat","guid":"a",
  "geometry":{"DC":6,"NOF":3,"LCF":18,"LB":30,"OAL":60,"SFDM":6,"HAND":true,"RE":0},
  "holder":{"segments":[{"height":10,"lower-diameter":20,"upper-diameter":20},
                        {"height":5,"lower-diameter":20,"upper-diameter":32},
                        {"height":40,"lower-diameter":40,"upper-diameter":40}]},
  "post-process":{"number":1,"length-offset":1}},
 {"type":"ball end mill","unit":"millimeters","geometry":{"DC":8,"NOF":2,"LCF":16,"LB":40,"SFDM":8},"post-process":{"number":2}},
 {"type":"bull nose end mill","unit":"millimeters","geometry":{"DC":10,"NOF":4,"LCF":22,"RE":1.5},"post-process":{"number":3}},
 {"type":"chamfer mill","unit":"millimeters","geometry":{"DC":12,"NOF":4,"LCF":8,"TA":45,"tip-diameter":2},"post-process":{"number":4}},
 {"type":"flat end mill","unit":"inches","geometry":{"DC":0.25,"NOF":2,"LCF":0.75,"LB":1.25},"post-process":{"number":5}}
]}"#;

#[test]
fn a_fusion_library_maps_every_modelled_field() {
    let lib = ToolLibrary::read(FUSION).unwrap();
    assert_eq!(lib.format, "fusion360");
    assert_eq!(lib.tools.len(), 5);
    let t1 = &lib.tools[&1];
    assert_eq!(
        (t1.shape, t1.diameter, t1.flutes, t1.flute_length),
        (ToolShape::Flat, 6.0, 3, 18.0)
    );
    assert_eq!((t1.stick_out, t1.shank_diameter), (Some(30.0), Some(6.0)));
    assert_eq!(t1.name.as_deref(), Some("6 mm flat"));
    let stack: Vec<(f64, f64, f64)> = t1
        .holder
        .iter()
        .map(|h| (h.length, h.bottom_diameter, h.top_diameter))
        .collect();
    assert_eq!(
        stack,
        vec![(10.0, 20.0, 20.0), (5.0, 20.0, 32.0), (40.0, 40.0, 40.0)]
    );
    let t2 = &lib.tools[&2];
    assert_eq!(
        (t2.shape, t2.diameter, t2.corner_radius, t2.flutes),
        (ToolShape::Ball, 8.0, 4.0, 2)
    );
    let t3 = &lib.tools[&3];
    assert_eq!(
        (t3.shape, t3.corner_radius, t3.flutes),
        (ToolShape::BullNose, 1.5, 4)
    );
    let t4 = &lib.tools[&4];
    assert_eq!(
        (t4.shape, t4.taper_half_angle_deg, t4.tip_diameter),
        (ToolShape::Chamfer, 45.0, 2.0)
    );
    // Inches converted.
    let t5 = &lib.tools[&5];
    assert!((t5.diameter - 6.35).abs() < 1e-12 && (t5.flute_length - 19.05).abs() < 1e-12);
    assert_eq!(t5.stick_out, Some(31.75));
    // What is not modelled is listed, not dropped.
    let unmodelled: Vec<(&str, &str)> = lib
        .report
        .unmodelled
        .iter()
        .map(|n| (n.tool.as_str(), n.field.as_str()))
        .collect();
    assert!(
        unmodelled.contains(&("T1 (data[0])", "geometry.OAL")),
        "{unmodelled:?}"
    );
    assert!(unmodelled.contains(&("T1 (data[0])", "geometry.HAND")));
    // Helix not given anywhere: assumed and said.
    assert!(lib
        .report
        .assumed
        .iter()
        .any(|n| n.tool == "T2 (data[1])" && n.field == "helix_deg"));
}

#[test]
fn a_fusion_tool_millsim_does_not_model_is_refused_naming_tool_and_field() {
    let bad =
        r#"{"data":[{"type":"thread mill","geometry":{"DC":6},"post-process":{"number":7}}]}"#;
    let e = ToolLibrary::read(bad).unwrap_err();
    assert_eq!(
        (e.tool.as_str(), e.field.as_str()),
        ("T7 (data[0])", "type")
    );
    assert!(e.to_string().contains("thread mill"), "{e}");
    let no_number = r#"{"data":[{"type":"flat end mill","geometry":{"DC":6}}]}"#;
    let e = ToolLibrary::read(no_number).unwrap_err();
    assert_eq!(e.field, "post-process.number");
    let bull = r#"{"data":[{"type":"bull nose end mill","geometry":{"DC":6},"post-process":{"number":1}}]}"#;
    assert_eq!(ToolLibrary::read(bull).unwrap_err().field, "geometry.RE");
}

#[test]
fn linuxcnc_tables_and_csv_read_with_their_assumptions() {
    let tbl = "T1 P1 D6.0 Z+25.0 ;6mm ball end mill\nT2 P2 D10 Z+30 ;\n";
    let lib = ToolLibrary::read(tbl).unwrap();
    assert_eq!(lib.format, "linuxcnc");
    assert_eq!(
        (lib.tools[&1].shape, lib.tools[&1].diameter),
        (ToolShape::Ball, 6.0)
    );
    assert_eq!(lib.tools[&2].shape, ToolShape::Flat);
    assert!(lib
        .report
        .assumed
        .iter()
        .any(|n| n.tool.starts_with("T2 ") && n.field == "type"));
    let e = ToolLibrary::read("T3 P3 Dx\n").unwrap_err();
    assert_eq!((e.tool.as_str(), e.field.as_str()), ("line 1", "D"));

    let csv = "number,type,diameter,corner_radius,flutes,flute_length,helix\n4,bull,12,2,4,30,35\n5,ball,6,,2,12,30\n";
    let lib = ToolLibrary::read(csv).unwrap();
    assert_eq!(lib.format, "csv");
    let t4 = &lib.tools[&4];
    assert_eq!(
        (
            t4.shape,
            t4.diameter,
            t4.corner_radius,
            t4.flutes,
            t4.flute_length,
            t4.helix_deg
        ),
        (ToolShape::BullNose, 12.0, 2.0, 4, 30.0, 35.0)
    );
    assert_eq!(lib.tools[&5].corner_radius, 3.0);
    let e = ToolLibrary::read("number,diameter,colour\n1,6,red\n").unwrap_err();
    assert_eq!(e.field, "colour");
}

#[test]
fn header_comments_describe_tools_with_every_assumed_value_named() {
    let program = "(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)\n(T2 D=6 CR=3 - ZMIN=-5 - ball end mill)\n(T3 D=0.25 CR=0.02 - bull nose end mill)\nG20\nT1 M6\n";
    let lib = tools_from_header(program);
    assert_eq!(
        (lib.tools[&1].shape, lib.tools[&1].diameter),
        (ToolShape::Flat, 2.65 * 25.4)
    );
    assert_eq!(lib.tools[&2].shape, ToolShape::Ball);
    assert!((lib.tools[&3].corner_radius - 0.02 * 25.4).abs() < 1e-12);
    let assumed: Vec<(&str, &str)> = lib
        .report
        .assumed
        .iter()
        .map(|n| (n.tool.as_str(), n.field.as_str()))
        .collect();
    for field in ["flutes", "flute_length_mm", "helix_deg"] {
        assert!(assumed.contains(&("T1 (line 1)", field)), "{assumed:?}");
    }
    let mastercam = tools_from_header("( TOOL - 4 DIA. OFF. - 4 LEN. - 4 DIA. - 10. )\nG21\n");
    assert_eq!(mastercam.tools[&4].diameter, 10.0);
}

#[test]
fn mastercam_piped_header_comments_describe_tools() {
    // As Mastercam's Fanuc posts write the tool list: the size leads the name.
    let program = "%\nO0000(ACRYLIC TOP)\n( T212 |    3. FLAT ENDMILL | H0 )\n( T2 | 6. BALL ENDMILL | H2 )\n( T3 | 1/4 FLAT ENDMILL | H3 | D3 | TOOL DIA. - 6.5 )\n( T4 | 1/4 DRILL | H4 )\n( T5 | 10. BULL ENDMILL 1. RAD | H5 )\n( T6 | #7 DRILL | H6 )\n(T7 | MY TOOL | no offset field)\nN1 G21\n";
    let lib = tools_from_header(program);
    assert_eq!(
        (lib.tools[&212].shape, lib.tools[&212].diameter),
        (ToolShape::Flat, 3.0)
    );
    assert_eq!(
        (lib.tools[&2].shape, lib.tools[&2].diameter),
        (ToolShape::Ball, 6.0)
    );
    // TOOL DIA. wins over the name's size.
    assert_eq!(lib.tools[&3].diameter, 6.5);
    // An inch fraction in a metric program is inches.
    assert_eq!(
        (lib.tools[&4].shape, lib.tools[&4].diameter),
        (ToolShape::Drill, 6.35)
    );
    assert_eq!(
        (lib.tools[&5].shape, lib.tools[&5].corner_radius),
        (ToolShape::BullNose, 1.0)
    );
    // A letter/number drill names no size; a comment without the offset field is not the form.
    assert!(!lib.tools.contains_key(&6) && !lib.tools.contains_key(&7));
    // In an inch program a decimal size is inches.
    let inch = tools_from_header("( T1 | .5 FLAT ENDMILL | H1 )\nG20\n");
    assert!((inch.tools[&1].diameter - 12.7).abs() < 1e-12);
}

#[test]
fn a_header_tool_flutes_reach_its_zmin() {
    // The README example's tool: Ø2.65, ZMIN=-12.55 below a program zero on the stock's top;
    // 3·D = 7.95 mm of flutes would call every cut below 7.95 mm deep past the flutes.
    let lib = tools_from_header("(T1  D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)\n(T2 D=10 CR=0 - ZMIN=-4 - flat end mill)\nG21\n");
    assert_eq!(lib.tools[&1].flute_length, 13.0);
    let note = lib
        .report
        .assumed
        .iter()
        .find(|n| n.tool == "T1 (line 1)" && n.field == "flute_length_mm")
        .unwrap();
    assert!(note.note.contains("ZMIN=-12.55"), "{}", note.note);
    assert_eq!(
        lib.report
            .assumed
            .iter()
            .filter(|n| n.tool == "T1 (line 1)" && n.field == "flute_length_mm")
            .count(),
        1
    );
    // A shallow ZMIN keeps the 3·D default.
    assert_eq!(lib.tools[&2].flute_length, 30.0);
}

fn adaptive_spec(tools: BTreeMap<u32, Tool>) -> Option<SimulateSpec> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/adaptive");
    let program = std::fs::read_to_string(format!("{dir}/1055_utab_265bit.nc")).ok()?;
    let mut machine: Machine =
        serde_json::from_str(&std::fs::read_to_string(format!("{dir}/machine.json")).ok()?).ok()?;
    machine.energy = None;
    let stock: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(format!("{dir}/stock.json")).ok()?).ok()?;
    let (min, max) = (
        serde_json::from_value(stock["min"].clone()).ok()?,
        serde_json::from_value(stock["max"].clone()).ok()?,
    );
    Some(SimulateSpec {
        program,
        interpret: InterpretOptions::default(),
        stock: StockSource::Shape(StockShape::Block { min, max }),
        tools,
        material: Material::builtin("Al7075-T6").unwrap(),
        machine,
        cell: Some(0.1),
        memory_limit: 1 << 30,
        force_positions: 90,
        optimize: None,
        axes: Default::default(),
        workpiece: None,
        chatter: None,
        part: None,
        fixture: None,
    })
}

#[test]
fn the_example_job_runs_with_its_tool_from_a_library_or_from_its_own_header() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/adaptive");
    let tool_json: Tool =
        serde_json::from_str(&std::fs::read_to_string(format!("{dir}/tool.json")).unwrap())
            .unwrap();
    let run = |tools| {
        simulate(
            &adaptive_spec(tools).unwrap(),
            &CancelFlag::new(),
            &NoProgress,
        )
        .unwrap()
    };
    // The program selects T1 but never loads it (no M6): one tool for every move, key 0.
    let reference = run(BTreeMap::from([(0, tool_json.clone())]));

    // The same tool from a Fusion library: the same forces.
    let lib = ToolLibrary::read(
        r#"{"data":[{"type":"flat end mill","unit":"millimeters","description":"2.65 mm 2-flute flat end mill",
            "geometry":{"DC":2.65,"NOF":2,"LCF":14,"LB":20,"SFDM":3.175,"helix-angle":30},
            "holder":{"segments":[{"height":25,"lower-diameter":20,"upper-diameter":20}]},
            "post-process":{"number":1}}]}"#,
    )
    .unwrap();
    assert_eq!(lib.tools[&1], tool_json);
    // The library's tools by number, as a job gives them (with one the program never uses):
    // T1, the number the program selects, cuts every move.
    let mut tools = lib.tools.clone();
    tools.insert(9, Tool::ball(0.5, 2));
    let from_library = run(tools);
    assert_eq!(
        from_library.summary.peak_force,
        reference.summary.peak_force
    );
    assert_eq!(from_library.tool_numbers, vec![1]);
    assert!(from_library.summary.tool_warnings.is_empty());

    // No tool at all: T1 from the header comment `(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end
    // mill)`, 2 flutes and a 30° helix assumed (as tool.json has them), flutes reaching ZMIN
    // (13 mm: with 3·D, 7.95 mm, the deeper cuts read as past the flutes).
    let header = run(BTreeMap::new());
    let warnings = &header.summary.tool_warnings;
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with("T1 (line 2)")
            && warnings[0].contains("flute_length_mm")
            && warnings[0].contains("ZMIN"),
        "{warnings:?}"
    );
    assert_eq!(
        header.summary.flute_length_exceeded_moves, 0,
        "{:?}",
        header.summary
    );
    // Where the geometry agrees (tool.json with the assumed flute length and no shank or
    // holder), the same forces and the same cut.
    let mut same = tool_json.clone();
    same.flute_length = 13.0;
    same.shank_diameter = None;
    same.stick_out = None;
    same.holder.clear();
    let agreeing = run(BTreeMap::from([(0, same)]));
    assert_eq!(header.summary.peak_force, agreeing.summary.peak_force);
    assert_eq!(
        header.rows.iter().map(|r| r.mean_force).collect::<Vec<_>>(),
        agreeing
            .rows
            .iter()
            .map(|r| r.mean_force)
            .collect::<Vec<_>>()
    );
    assert_eq!(
        header.summary.removed_volume,
        agreeing.summary.removed_volume
    );
}

#[test]
fn a_library_with_many_unknown_fields_keeps_a_bounded_report() {
    // 600 tools with two fields millsim does not model, one of them a long value: 1,200
    // notes, of which the first 500 are kept (each at most 200 characters and an ellipsis)
    // and the rest counted.
    let long = "x".repeat(5000);
    let tools: Vec<String> = (1..=600)
        .map(|n| {
            format!(
                r#"{{"type":"flat end mill","unit":"millimeters","geometry":{{"DC":6,"NOF":2,"LCF":18,"vendor-a":"{long}","vendor-b":1}},"post-process":{{"number":{n}}}}}"#
            )
        })
        .collect();
    let lib = ToolLibrary::read(&format!(r#"{{"data":[{}]}}"#, tools.join(","))).unwrap();
    assert_eq!(lib.tools.len(), 600);
    let r = &lib.report;
    assert_eq!(r.unmodelled.len(), millsim_engine::tool_library::MAX_NOTES);
    assert_eq!(r.unmodelled.len() + r.unmodelled_omitted, 1200);
    assert!(
        r.unmodelled.iter().all(|n| n.note.chars().count() <= 201),
        "a note is unbounded"
    );
    let json = serde_json::to_string(r).unwrap();
    assert!(json.len() < 200_000, "{} bytes of report", json.len());
    assert!(
        json.contains("\"unmodelled_omitted\":700"),
        "{}",
        &json[json.len() - 100..]
    );
    // Every note is counted by its field, the omitted ones too.
    assert_eq!(r.unmodelled_by_field["geometry.vendor-a"], 600);
    assert_eq!(r.unmodelled_by_field["geometry.vendor-b"], 600);
}

#[test]
fn a_report_counts_at_most_500_fields_by_name() {
    use millsim_engine::tool_library::{MAX_FIELDS, OTHER_FIELDS};
    // One tool naming 600 fields millsim does not model: 500 counted by name, the other
    // 100 under one key, so that the counts are bounded whatever the file names.
    let fields: Vec<String> = (0..600).map(|k| format!(r#""f{k:03}":1"#)).collect();
    let lib = ToolLibrary::read(&format!(
        r#"{{"data":[{{"type":"flat end mill","geometry":{{"DC":6,{}}},"post-process":{{"number":1}}}}]}}"#,
        fields.join(",")
    ))
    .unwrap();
    let counts = &lib.report.unmodelled_by_field;
    assert_eq!(counts.len(), MAX_FIELDS + 1);
    assert_eq!(counts[OTHER_FIELDS], 100);
    assert_eq!(counts.values().sum::<usize>(), 600);
}
