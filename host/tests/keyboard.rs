//! The one resolution of a keyboard: built-in and file layouts agree, a single instrument
//! gets its keys and its board's sample rate, and bad input is an error naming the field.

use tactus_host::keyboard::{self, KeyboardError, KeyboardSpec};

fn spec(input: &str) -> KeyboardSpec<'_> {
    KeyboardSpec {
        input,
        as_layout: None,
        board: None,
        keys: None,
        params: &[],
    }
}

fn quiet(
) -> impl FnMut(&tactus_host::catalogue::Source, &[tactus_compiler::diagnostics::Diagnostic]) {
    |_, _| {}
}

fn root(p: &str) -> String {
    format!("{}/../{p}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn a_built_in_layout_is_its_file() {
    let by_name = keyboard::compile(&spec("grand88"), &mut quiet()).unwrap();
    let path = root("instruments/layouts/grand88.toml");
    let by_file = keyboard::compile(&spec(&path), &mut quiet()).unwrap();
    assert_eq!(by_name.name, "grand88");
    assert_eq!(by_name.keys, by_file.keys);
    assert_eq!(by_name.key_set, by_file.key_set);
    assert_eq!(by_name.keys.len(), 88);
    assert_eq!(by_name.keys[0].key, 21);
    assert_eq!(by_name.keys[87].key, 108);
    // The hammer mass is graded: one set per key, each lowered once.
    assert_eq!(by_name.sets.len(), 88);
    assert_eq!(by_name.board.name, "rp2040");
    assert!(by_name.boards.is_none());
    for (a, b) in by_name.sets.iter().zip(&by_file.sets) {
        assert_eq!(a.params, b.params);
        assert_eq!(a.ir, b.ir);
    }
}

#[test]
fn an_override_replaces_a_graded_param_on_every_key() {
    let params = [("M_h".to_string(), "9 g".to_string())];
    let kb = keyboard::compile(
        &KeyboardSpec {
            params: &params,
            ..spec("grand88")
        },
        &mut quiet(),
    )
    .unwrap();
    assert_eq!(
        kb.sets.len(),
        1,
        "one hammer mass on every key: one program"
    );
    assert!(
        kb.keys.iter().all(|a| a.params == params),
        "{:?}",
        kb.keys[0]
    );
    assert_eq!(
        keyboard::with_overrides(
            &[("a".into(), "1 m".into()), ("b".into(), "2 m".into())],
            &[("a".into(), "3 m".into())]
        ),
        [
            ("b".to_string(), "2 m".to_string()),
            ("a".into(), "3 m".into())
        ]
    );
}

#[test]
fn a_single_instrument_gets_88_keys_its_overrides_and_the_board_rate() {
    let params = [("M_h".to_string(), "9 g".to_string())];
    let kb = keyboard::compile(
        &KeyboardSpec {
            params: &params,
            board: Some("rp2040_200mhz"),
            ..spec("grand_piano")
        },
        &mut quiet(),
    )
    .unwrap();
    assert_eq!(kb.name, "grand_piano × 88");
    assert_eq!(kb.keys.len(), 88);
    assert_eq!(kb.sets.len(), 1, "one instrument, one set, lowered once");
    assert!(kb.keys.iter().all(|a| a.params == params));
    assert_eq!(kb.sets[0].ir.sample_rate_hz, kb.board.sample_rate_hz);
    let twelve = keyboard::compile(
        &KeyboardSpec {
            keys: Some(12),
            ..spec("harpsichord")
        },
        &mut quiet(),
    )
    .unwrap();
    let keys: Vec<u8> = twelve.keys.iter().map(|a| a.key).collect();
    assert_eq!(keys, (21..33).collect::<Vec<u8>>());
    assert_eq!(twelve.key_programs().len(), 12);
}

#[test]
fn bad_input_names_the_field() {
    let err = |s: KeyboardSpec| keyboard::compile(&s, &mut quiet()).unwrap_err().to_string();
    assert!(err(KeyboardSpec {
        keys: Some(4),
        ..spec("grand88")
    })
    .contains("--keys is for a single instrument"));
    assert!(err(KeyboardSpec {
        keys: Some(0),
        ..spec("grand_piano")
    })
    .contains("--keys must be between 1 and 128"));
    assert!(err(KeyboardSpec {
        board: Some("no_such_board"),
        ..spec("grand88")
    })
    .contains("no built-in board"));
    assert!(err(spec("no_such_instrument")).contains("no built-in instrument"));
    // `--layout` forces a layout: an instrument's name is not one.
    assert!(err(KeyboardSpec {
        as_layout: Some(true),
        ..spec("grand_piano")
    })
    .contains("grand_piano"));
    // A layout whose board kind does not exist: the file and the field.
    let dir = std::env::temp_dir().join(format!("tactus-host-kb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("l.toml");
    std::fs::write(
        &path,
        "name = \"l\"\nboard_kind = \"nope\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"harpsichord\"\n",
    )
    .unwrap();
    let e = err(spec(path.to_str().unwrap()));
    assert!(e.contains("l.toml") && e.contains("`board_kind`"), "{e}");
    // An instrument that does not compile: its diagnostics reported once, the key named.
    let bad = dir.join("bad.tactus");
    std::fs::write(&bad, "instrument bad { nonsense }").unwrap();
    let mut reported = 0;
    let e = keyboard::compile(&spec(bad.to_str().unwrap()), &mut |_, d| {
        assert!(!d.is_empty());
        reported += 1;
    })
    .unwrap_err();
    assert!(matches!(e, KeyboardError::Compile { key: 21, .. }), "{e}");
    assert_eq!(reported, 1);
    // In a layout (its sets lowered in parallel), the first bad key in key order is the
    // error, and only its diagnostics are reported: a graded range that compiles, then a
    // range that does not parse, then a file that cannot be read (not UTF-8).
    let graded = "[[range]]\nkeys = [48, 59]\ninstrument = \"grand_piano\"\n\
                  grade = [ { param = \"M_h\", from = \"11 g\", to = \"5 g\" } ]\n";
    let layout = |ranges: &[(u8, u8, &str)]| {
        let mut text = "name = \"l\"\n".to_string() + graded;
        for (lo, hi, instrument) in ranges {
            text += &format!("[[range]]\nkeys = [{lo}, {hi}]\ninstrument = {instrument:?}\n");
        }
        text
    };
    let unreadable = dir.join("binary.tactus");
    std::fs::write(&unreadable, [0xff, 0xfe, 0x00, 0x80]).unwrap();
    let bad_path = bad.to_str().unwrap();
    let unreadable_path = unreadable.to_str().unwrap();
    for (ranges, key, reports) in [
        (vec![(60, 61, bad_path), (62, 62, unreadable_path)], 60, 1),
        (vec![(60, 61, unreadable_path), (62, 63, bad_path)], 60, 0),
    ] {
        let path = dir.join("bad_layout.toml");
        std::fs::write(&path, layout(&ranges)).unwrap();
        let mut reported = 0;
        let e = keyboard::compile(&spec(path.to_str().unwrap()), &mut |_, d| {
            assert!(!d.is_empty());
            reported += 1;
        })
        .unwrap_err();
        let text = e.to_string();
        match reports {
            1 => assert!(
                matches!(e, KeyboardError::Compile { key: k, .. } if k == key),
                "{text}"
            ),
            _ => assert!(text.contains(&format!("key {key}")), "{text}"),
        }
        assert_eq!(reported, reports, "{text}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn play_gets_the_played_keys_and_refuses_a_pen() {
    let kb = keyboard::compile(&spec("split_harpsichord_piano"), &mut quiet()).unwrap();
    let played = [30u8, 31, 70].into_iter().collect();
    let p = kb.played(&played, None, None).unwrap();
    assert_eq!(p.keys.len(), 88, "the firmware runs every key");
    assert_eq!(p.key_program.len(), 3);
    // Keys 30 and 31 share the harpsichord; 70 is a graded piano key.
    assert_eq!(p.programs.len(), 2);
    assert_eq!(p.key_program[&30], p.key_program[&31]);
    assert!(p.firmware.is_none());
    // A pen instrument is one pen, and `play` does not move pens.
    let pen = keyboard::compile(&spec("bowed_string"), &mut quiet()).unwrap();
    assert!(pen.sets[0].ir.is_pen());
    assert_eq!(pen.keys.len(), 1, "a pen is one pen");
    let one = pen.keys.iter().map(|a| a.key).collect();
    let Err(e) = pen.played(&one, None, None) else {
        panic!("play took a pen");
    };
    let e = e.to_string();
    assert!(e.contains("a pen"), "{e}");
}

/// The keyboard's one plan: planned when the layout lists no boards (the fewest that fit,
/// every key once, in order), the layout's own checked when it does.
#[test]
fn the_plan_is_the_layouts_boards_or_planned() {
    let kb = keyboard::compile(
        &KeyboardSpec {
            keys: Some(40),
            ..spec("hammond")
        },
        &mut quiet(),
    )
    .unwrap();
    let programs = kb.firmware().unwrap();
    let plan = kb.plan(&programs, &mut |_, _| {}).unwrap();
    assert!(plan.planned);
    assert_eq!(
        plan.key_lists().concat(),
        (21..61).collect::<Vec<u8>>(),
        "every key once, in order"
    );
    assert!(plan.boards.iter().all(|b| b.fits()));
    // 28 hammond keys fit a board (BENCHMARKS.md): 40 keys take two.
    assert_eq!(plan.boards.len(), 2);

    let dir = std::env::temp_dir().join(format!("tactus-plan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let layout = dir.join("two.toml");
    std::fs::write(
        &layout,
        "name = \"two\"\n[[range]]\nkeys = [21, 40]\ninstrument = \"hammond\"\n\
         [[board]]\nkeys = [21, 30]\n[[board]]\nkeys = [31, 40]\n",
    )
    .unwrap();
    let kb = keyboard::compile(&spec(&layout.display().to_string()), &mut quiet()).unwrap();
    let programs = kb.firmware().unwrap();
    let plan = kb.plan(&programs, &mut |_, _| {}).unwrap();
    assert!(!plan.planned);
    assert_eq!(
        plan.key_lists(),
        [(21..=30).collect::<Vec<u8>>(), (31..=40).collect()]
    );
    assert!(plan.boards.iter().all(|b| b.fits()));
    std::fs::remove_dir_all(&dir).unwrap();
}
