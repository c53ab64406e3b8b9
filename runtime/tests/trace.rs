//! Building traces and writing them as CSV.

use tactus_runtime::trace::{ColumnKind, Trace, TraceError};

fn sample_trace() -> Trace {
    let mut t = Trace::new(44_100.0);
    assert_eq!(t.add_column("t", "s", ColumnKind::Time), 0);
    assert_eq!(t.add_column("key", "m", ColumnKind::Sensor), 1);
    assert_eq!(t.add_column("spring", "N", ColumnKind::Force), 2);
    assert_eq!(t.add_column("viscous", "N", ColumnKind::Force), 3);
    assert_eq!(t.add_column("total", "N", ColumnKind::TotalForce), 4);
    assert_eq!(t.add_column("jack", "", ColumnKind::Mode), 5);
    assert_eq!(t.add_column("strike", "m/s", ColumnKind::Event), 6);
    t.push_row(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f64::NAN])
        .unwrap();
    t.push_row(&[
        1.0 / 44_100.0,
        1e-7,
        0.1 + 0.2,
        -1.5e-300,
        0.1 + 0.2 - 1.5e-300,
        1.0,
        3.25,
    ])
    .unwrap();
    t
}

#[test]
fn rows_and_lookups() {
    let t = sample_trace();
    assert_eq!(t.len(), 2);
    assert!(!t.is_empty());
    assert_eq!(t.column("spring").unwrap().values, vec![0.0, 0.1 + 0.2]);
    assert_eq!(t.column_index("total"), Some(4));
    assert!(t.column("nope").is_none());
    let forces: Vec<&str> = t
        .columns_of(ColumnKind::Force)
        .map(|c| c.name.as_str())
        .collect();
    assert_eq!(forces, ["spring", "viscous"]);
    assert_eq!(t.times_s(), vec![0.0, 1.0 / 44_100.0]);
}

#[test]
fn push_row_rejects_wrong_lengths_and_leaves_the_trace_alone() {
    let mut t = sample_trace();
    let before = t.clone();
    let e = t.push_row(&[1.0, 2.0]).unwrap_err();
    assert!(matches!(
        e,
        TraceError::RowLength {
            row: 2,
            expected: 7,
            got: 2
        }
    ));
    assert!(e.to_string().contains("row 2"), "{e}");
    // (Debug text, not `==`: the event column holds NaN, which is not equal to itself.)
    assert_eq!(format!("{t:?}"), format!("{before:?}"));
}

#[test]
fn late_columns_are_padded_with_nan() {
    let mut t = Trace::new(1000.0);
    t.add_column("key", "m", ColumnKind::Sensor);
    t.push_row(&[0.001]).unwrap();
    t.push_row(&[0.002]).unwrap();
    let i = t.add_column("hammer", "m", ColumnKind::State);
    assert_eq!(t.len(), 2);
    assert!(t.columns[i].values.iter().all(|v| v.is_nan()));
    // Without a Time column, times come from the sample rate.
    assert_eq!(t.times_s(), vec![0.0, 0.001]);
}

#[test]
fn csv_has_unit_headers_exact_values_and_empty_nans() {
    let t = sample_trace();
    let mut out = Vec::new();
    t.write_csv(&mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(
        lines[0],
        "t [s],key [m],spring [N],viscous [N],total [N],jack,strike [m/s]"
    );
    assert_eq!(lines[1], "0,0,0,0,0,0,");
    // Every value reads back to the same bits.
    let cells: Vec<f64> = lines[2].split(',').map(|c| c.parse().unwrap()).collect();
    let row: Vec<f64> = t.columns.iter().map(|c| c.values[1]).collect();
    assert_eq!(cells.len(), row.len());
    for (a, b) in cells.iter().zip(&row) {
        assert_eq!(a.to_bits(), b.to_bits(), "{a} vs {b}");
    }
}

#[test]
fn csv_file_is_written_and_errors_name_the_path() {
    let t = sample_trace();
    let dir = std::env::temp_dir();
    let path = dir.join(format!("tactus-trace-{}.csv", std::process::id()));
    t.write_csv_file(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert!(text.starts_with("t [s],key [m]"));
    assert_eq!(text.lines().count(), 3);

    let bad = dir
        .join(format!("tactus-no-such-dir-{}", std::process::id()))
        .join("trace.csv");
    let e = t.write_csv_file(&bad).unwrap_err();
    assert!(matches!(e, TraceError::Io { .. }));
    assert!(e.to_string().contains("trace.csv"), "{e}");
}
