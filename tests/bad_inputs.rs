//! Every file under `tests/bad_inputs/` is a malformed scenario whose first line says
//! `# expect: <fragment>`. `deasim check` must reject each with exit status 2 and a message that
//! names the file and contains the fragment — never a panic, never Rust debug text (`Some("…")`)
//! and never a number written out in tens of digits.

use std::process::Command;

#[test]
fn every_bad_input_is_rejected_with_a_clear_message() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad_inputs");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(files.len() >= 40, "{} cases", files.len());
    let mut failures = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        let expect = text
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("# expect: "))
            .unwrap_or_else(|| panic!("{}: first line must be `# expect: ...`", file.display()))
            .trim()
            .to_string();
        let out = Command::new(env!("CARGO_BIN_EXE_deasim"))
            .arg("check")
            .arg(file)
            .output()
            .unwrap();
        let msg = String::from_utf8_lossy(&out.stdout).into_owned()
            + &String::from_utf8_lossy(&out.stderr);
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        // no Rust debug text and no number written out in tens of digits
        let debug_text = ["Some(", "None", "\\\""].iter().any(|d| msg.contains(d));
        let long_number = msg
            .split(|c: char| !c.is_ascii_digit())
            .any(|run| run.len() > 20);
        if out.status.code() != Some(2)
            || !msg.contains(&expect)
            || !msg.contains(&name)
            || msg.contains("panicked")
            || debug_text
            || long_number
        {
            failures.push(format!(
                "{name}: exit {:?}, expected `{expect}` in: {msg}",
                out.status.code()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
}
