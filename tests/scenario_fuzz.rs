//! The fuzz property of `fuzz/fuzz_targets/scenario.rs` on stable Rust (cargo-fuzz needs nightly):
//! mutations of the embedded examples — byte flips, truncations, random key/value insertions,
//! huge and non-finite numbers, deep nesting, binary bytes — go through parse → build without a
//! panic, and each case finishes within a time bound (no hang, no unbounded work: building a mesh
//! larger than the memory guard is refused before it is allocated).

use deasim::io::build::build;
use deasim::io::examples::EXAMPLES;
use deasim::io::scenario::parse;
use proptest::prelude::*;
use proptest::test_runner::Config;
use std::time::{Duration, Instant};

/// One mutation of a scenario text.
#[derive(Debug, Clone)]
enum Mutation {
    FlipByte(usize, u8),
    Truncate(usize),
    /// Insert `key = value` after line `n`.
    Insert(usize, String, String),
    /// Replace the value of line `n` (after its `=`) by `value`.
    Replace(usize, String),
    /// Insert raw bytes at a position.
    Bytes(usize, Vec<u8>),
}

fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-0.0".to_string()),
        Just("0".to_string()),
        Just("18446744073709551615".to_string()),
        Just("9223372036854775807".to_string()),
        Just("[1e9, 1e9, 1e9]".to_string()),
        Just("[100000, 1, 1]".to_string()),
        Just("\"\"".to_string()),
        Just("\"z1\"".to_string()),
        Just("{ waveform = \"sine\", amplitude = 1e300, frequency = 1e300 }".to_string()),
        (1usize..200).prop_map(|d| format!("{}1{}", "[".repeat(d), "]".repeat(d))),
        (1usize..200).prop_map(|d| format!("{}{}", "{ a = ".repeat(d), "1 }".repeat(d))),
        any::<f64>().prop_map(|x| format!("{x:e}")),
        any::<i64>().prop_map(|x| x.to_string()),
        "[a-z_.]{0,12}".prop_map(|s| format!("\"{s}\"")),
    ]
}

fn key() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("steps".to_string()),
        Just("dt".to_string()),
        Just("duration".to_string()),
        Just("divisions".to_string()),
        Just("size".to_string()),
        Just("mu".to_string()),
        Just("permittivity".to_string()),
        Just("fields_every".to_string()),
        Just("set".to_string()),
        Just("voltage".to_string()),
        "[a-z_]{1,10}",
    ]
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::FlipByte(i, b)),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), key(), value()).prop_map(|(n, k, v)| Mutation::Insert(n, k, v)),
        (any::<usize>(), value()).prop_map(|(n, v)| Mutation::Replace(n, v)),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| Mutation::Bytes(i, b)),
    ]
}

fn apply(text: &str, m: &Mutation) -> Vec<u8> {
    let mut b = text.as_bytes().to_vec();
    match m {
        Mutation::FlipByte(i, x) => {
            let i = i % b.len();
            b[i] ^= x | 1;
        }
        Mutation::Truncate(i) => b.truncate(i % b.len()),
        Mutation::Insert(n, k, v) => {
            let lines: Vec<&str> = text.lines().collect();
            let n = n % (lines.len() + 1);
            let mut out = lines[..n].join("\n");
            out.push_str(&format!("\n{k} = {v}\n"));
            out.push_str(&lines[n..].join("\n"));
            b = out.into_bytes();
        }
        Mutation::Replace(n, v) => {
            let mut lines: Vec<String> = text.lines().map(String::from).collect();
            let assignments: Vec<usize> = (0..lines.len())
                .filter(|&i| lines[i].contains(" = ") && !lines[i].starts_with('#'))
                .collect();
            if assignments.is_empty() {
                return b;
            }
            let i = assignments[n % assignments.len()];
            let key = lines[i].split(" = ").next().unwrap_or("").to_string();
            lines[i] = format!("{key} = {v}");
            b = lines.join("\n").into_bytes();
        }
        Mutation::Bytes(i, x) => {
            let i = i % (b.len() + 1);
            b.splice(i..i, x.iter().copied());
        }
    }
    b
}

/// parse → build of one input; returns how long it took.
fn check(bytes: &[u8]) -> Duration {
    let start = Instant::now();
    if let Ok(text) = std::str::from_utf8(bytes) {
        if let Ok(s) = parse(text, "fuzz.toml", &[]) {
            let _ = build(&s, "fuzz.toml", None);
        }
    }
    start.elapsed()
}

proptest! {
    #![proptest_config(Config { cases: 400, failure_persistence: None, ..Config::default() })]

    /// Up to three mutations of an example: no panic, at most 10 s per case.
    #[test]
    fn mutated_examples_never_panic(
        example in 0..EXAMPLES.len(),
        mutations in prop::collection::vec(mutation(), 1..4),
    ) {
        let mut bytes = EXAMPLES[example].1.as_bytes().to_vec();
        for m in &mutations {
            let text = String::from_utf8_lossy(&bytes).into_owned();
            if text.is_empty() {
                break;
            }
            bytes = apply(&text, m);
        }
        let t = check(&bytes);
        prop_assert!(t < Duration::from_secs(10), "{t:?} for {mutations:?}");
    }
}

/// Hand-picked hostile inputs that the mutations may not reach.
#[test]
fn hostile_inputs_never_panic() {
    let deep_array = format!("name = {}1{}", "[".repeat(100_000), "]".repeat(100_000));
    let deep_table = format!("x = {}1{}", "{a=".repeat(10_000), "}".repeat(10_000));
    let long_key = format!("{} = 1", "a".repeat(1_000_000));
    let many_keys: String = (0..100_000).map(|i| format!("k{i} = {i}\n")).collect();
    let inputs: Vec<Vec<u8>> = vec![
        deep_array.into_bytes(),
        deep_table.into_bytes(),
        long_key.into_bytes(),
        many_keys.into_bytes(),
        vec![0u8; 100_000],
        (0..=255u8).cycle().take(70_000).collect(),
        b"[mesh]\ngenerator = \"box\"\nsize = [1e308, 1e308, 1e308]\ndivisions = [1, 1, 1]\n"
            .to_vec(),
    ];
    for b in &inputs {
        let t = check(b);
        assert!(t < Duration::from_secs(10), "{t:?}");
    }
}
