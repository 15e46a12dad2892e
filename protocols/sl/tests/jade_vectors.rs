//! Every row of JADE's SL answers (`fipa/vectors/sl-decode.jsonl`): same accept/reject per level,
//! same tree (JADE's `abs` rendering), and our printed text reads back as the same tree.

use iw_sl::{Level, jade_tree, parse};

fn level_of(codec: &str) -> Level {
    match codec {
        "SL0" => Level::Sl0,
        "SL1" => Level::Sl1,
        "SL2" => Level::Sl2,
        "SL(full)" => Level::Full,
        other => panic!("unknown codec {other}"),
    }
}

/// JADE prints byte arrays as `[B@<identity hash>`: compare up to the hash.
fn same_tree(ours: &str, jade: &str) -> bool {
    let mut a = ours.split("[B@");
    let mut b = jade.split("[B@");
    let (Some(a0), Some(b0)) = (a.next(), b.next()) else {
        return false;
    };
    if a0 != b0 {
        return false;
    }
    let skip_hash = |s: &str| {
        s.trim_start_matches(|c: char| c.is_ascii_hexdigit())
            .to_owned()
    };
    let (ra, rb): (Vec<_>, Vec<_>) = (a.map(skip_hash).collect(), b.map(skip_hash).collect());
    ra == rb
}

#[test]
fn every_sl_decode_row_agrees_with_jade() {
    let Some(path) = iw_testdata::require(
        "every_sl_decode_row_agrees_with_jade",
        "fipa/vectors/sl-decode.jsonl",
    ) else {
        return;
    };
    let text = std::fs::read_to_string(path).unwrap();
    let mut failures = vec![];
    let mut rows = 0;
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        rows += 1;
        let row: serde_json::Value = serde_json::from_str(line).unwrap();
        let input = row["input"].as_str().unwrap();
        let level = level_of(row["codec"].as_str().unwrap());
        let jade_ok = row["ok"].as_bool().unwrap();
        let source = row["source"].as_str().unwrap();
        match (parse(input, level), jade_ok) {
            (Ok(content), true) => {
                let ours = jade_tree(&content, level);
                let jade = row["abs"].as_str().unwrap();
                if !same_tree(&ours, jade) {
                    failures.push(format!(
                        "{source} {level}: tree differs\n ours: {ours}\n jade: {jade}"
                    ));
                }
                let printed = content.to_string();
                match parse(&printed, level) {
                    Ok(again) if again == content => {}
                    other => {
                        failures.push(format!("{source} {level}: reprint {printed} -> {other:?}"))
                    }
                }
            }
            (Err(_), false) => {}
            (Ok(_), false) => failures.push(format!(
                "{source} {level}: JADE refuses, we accept: {input}"
            )),
            (Err(e), true) => {
                failures.push(format!("{source} {level}: JADE accepts, we refuse: {e}"))
            }
        }
    }
    assert_eq!(rows, 332, "expected JADE's 332 rows");
    assert!(
        failures.is_empty(),
        "{} of {rows} rows disagree:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
