//! The command line's sink for what the library reports through the `log` facade: warnings and,
//! where a solver was asked to be verbose, its tables, each as one line on stderr.

/// Writes every record at `Info` or above to stderr, as its message alone.
struct StderrLog;

impl log::Log for StderrLog {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Info
    }

    fn log(&self, record: &log::Record) {
        if self.enabled(record.metadata()) {
            use std::io::Write;
            // one write per line, so that the lines of several MPI ranks do not interleave
            let _ = std::io::stderr().write_all(format!("{}\n", record.args()).as_bytes());
        }
    }

    fn flush(&self) {}
}

static LOGGER: StderrLog = StderrLog;

/// Installs the sink (once; later calls change nothing).
pub fn install() {
    if log::set_logger(&LOGGER).is_ok() {
        log::set_max_level(log::LevelFilter::Info);
    }
}
