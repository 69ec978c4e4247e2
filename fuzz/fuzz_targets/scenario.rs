//! Scenario parsing and validation never panic: any bytes → (UTF-8) → parse → build.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(s) = deasim::io::scenario::parse(text, "fuzz.toml", &[]) {
            let _ = deasim::io::build::build(&s, "fuzz.toml", None);
        }
    }
});
