//! Standard output that fails politely. `println!` panics when stdout is a closed pipe
//! (`tissue models | head -c0`) or a full disk (`> /dev/full`); the `outln!` / `out!`
//! macros write through the locked handle and return the error instead. `main` ends quietly
//! when the reader went away (`BrokenPipe`, as `head` does) and reports any other failure.

use std::fmt::Arguments;
use std::io::Write;

/// Writes `args` to standard output; with `newline`, a line.
pub fn write(args: Arguments<'_>, newline: bool) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(args)?;
    if newline {
        out.write_all(b"\n")?;
    }
    Ok(())
}

/// Flushes standard output (at exit: errors there would otherwise be lost).
pub fn flush() -> std::io::Result<()> {
    std::io::stdout().lock().flush()
}

/// Whether `e` is, at its root, the reader of our output having gone away.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// `println!` that returns an error (with `?`) instead of panicking.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::out::write(format_args!($($arg)*), true)
            .map_err(|e| anyhow::Error::new(e).context("writing to standard output"))?
    };
}

/// `print!` that returns an error (with `?`) instead of panicking.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::out::write(format_args!($($arg)*), false)
            .map_err(|e| anyhow::Error::new(e).context("writing to standard output"))?
    };
}
