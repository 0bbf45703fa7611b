//! A CSV file streamed row by row (`measures.csv`, `frames.csv`) that only ever ends at a
//! row boundary, and says what it kept when a write fails.
//!
//! [`RowFile::create`] writes the header ([`open_for_writing`]: never through a symbolic
//! link); [`RowFile::push`] adds a row to a buffer, handed to the operating system when it
//! passes 64 KiB and at every [`RowFile::flush`] (a process killed after a flush leaves those
//! rows in the file). A write can fail part-way (a full disk, `EFBIG` past the file size
//! limit), leaving part of a row: the file is then cut back to its last complete row, and the
//! error names the file, the operating system's reason and what the file keeps: the number of
//! complete rows and the first two fields of the last one (`step 560, time_s 5.6e-3`). After a
//! failure every write is refused. Dropping the value flushes what is buffered, cutting back
//! the same way if that fails.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::output::open_for_writing;
use crate::{Error, Result};

/// The buffer is written out when it passes this many bytes.
const BUFFER: usize = 1 << 16;

/// Where the rows go: a file, cut back with `set_len`.
trait Sink: Write + Send {
    fn set_len(&mut self, len: u64) -> std::io::Result<()>;
}

impl Sink for File {
    fn set_len(&mut self, len: u64) -> std::io::Result<()> {
        File::set_len(self, len)
    }
}

/// No file: the rows are counted and dropped ([`RowFile::discard`]).
struct Discard;

impl Write for Discard {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Sink for Discard {
    fn set_len(&mut self, _: u64) -> std::io::Result<()> {
        Ok(())
    }
}

/// A streamed CSV file (module docs).
pub struct RowFile {
    path: PathBuf,
    file: Box<dyn Sink>,
    header: String,
    /// Rows not yet handed to the operating system, each ending in `\n`.
    buf: Vec<u8>,
    /// Bytes in the file: the header and whole rows.
    on_disk: u64,
    /// Rows in the file, and the last of them (no newline; empty before the first).
    rows_on_disk: u64,
    last_on_disk: String,
    /// Rows pushed.
    rows: u64,
    /// The error of a failed write: every later write repeats it.
    failed: Option<String>,
}

impl RowFile {
    /// Create (truncate) `path` and write `header` (no newline) to it.
    pub fn create(path: &Path, header: &str) -> Result<RowFile> {
        let file = open_for_writing(path, true)?;
        Self::with_sink(path, Box::new(file), header)
    }

    /// Rows counted and dropped, no file written: a run that keeps its results in memory.
    /// `path` names what the file would have been, in messages.
    pub fn discard(path: &Path, header: &str) -> Result<RowFile> {
        Self::with_sink(path, Box::new(Discard), header)
    }

    /// [`RowFile::create`] writing into `file`, `path` naming it.
    fn with_sink(path: &Path, file: Box<dyn Sink>, header: &str) -> Result<RowFile> {
        let mut r = RowFile {
            path: path.to_path_buf(),
            file,
            header: header.to_string(),
            buf: Vec::with_capacity(BUFFER + 1024),
            on_disk: 0,
            rows_on_disk: 0,
            last_on_disk: String::new(),
            rows: 0,
            failed: None,
        };
        r.buf.extend_from_slice(header.as_bytes());
        r.buf.push(b'\n');
        r.flush_inner(true)?;
        Ok(r)
    }

    /// Append one row (`line` without its newline).
    pub fn push(&mut self, line: &[u8]) -> Result<()> {
        self.refuse_if_failed()?;
        self.buf.extend_from_slice(line);
        self.buf.push(b'\n');
        self.rows += 1;
        if self.buf.len() >= BUFFER {
            self.flush_inner(false)?;
        }
        Ok(())
    }

    /// Hand the buffered rows to the operating system.
    pub fn flush(&mut self) -> Result<()> {
        self.refuse_if_failed()?;
        self.flush_inner(false)
    }

    /// Rows pushed so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn refuse_if_failed(&self) -> Result<()> {
        match &self.failed {
            None => Ok(()),
            Some(msg) => Err(Error::io(&self.path, std::io::Error::other(msg.clone()))),
        }
    }

    /// Write the buffer; on a failure cut the file back to its last whole row (module docs).
    /// `header`: the buffer starts with the header line, not a row.
    fn flush_inner(&mut self, header: bool) -> Result<()> {
        let mut written = 0;
        let err = loop {
            if written == self.buf.len() {
                break None;
            }
            match self.file.write(&self.buf[written..]) {
                Ok(0) => break Some(std::io::Error::from(std::io::ErrorKind::WriteZero)),
                Ok(n) => written += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => break Some(e),
            }
        };
        let Some(err) = err else {
            let lines = &self.buf[..self.buf.len().saturating_sub(1)];
            let start = lines.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
            if !header {
                self.rows_on_disk += count_lines(&self.buf);
                self.last_on_disk = String::from_utf8_lossy(&lines[start..]).into_owned();
            }
            self.on_disk += self.buf.len() as u64;
            self.buf.clear();
            return Ok(());
        };
        // Whole lines that reached the file; the rest of the buffer is lost.
        let keep = self.buf[..written]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        let cut = (keep < written).then(|| self.file.set_len(self.on_disk + keep as u64));
        let kept = if header {
            match cut {
                Some(Err(e)) => format!("a partial header could not be cut off ({e})"),
                _ => "the file is left empty".to_string(),
            }
        } else {
            let kept_lines = &self.buf[..keep];
            self.rows_on_disk += count_lines(kept_lines);
            if keep > 0 {
                let lines = &kept_lines[..keep - 1];
                let start = lines.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
                self.last_on_disk = String::from_utf8_lossy(&lines[start..]).into_owned();
            }
            self.on_disk += keep as u64;
            let cut = match cut {
                None => String::new(),
                Some(Ok(())) => "; the partial row after them was cut off".to_string(),
                Some(Err(e)) => format!("; a partial row after them could not be cut off ({e})"),
            };
            format!("the file keeps its header and {}{cut}", self.kept_rows())
        };
        self.buf.clear();
        let msg = format!("{err}; {kept}");
        self.failed = Some(format!("an earlier write failed: {msg}"));
        Err(Error::io(&self.path, std::io::Error::new(err.kind(), msg)))
    }

    /// "N complete rows, the last `step 560, time_s 5.6e-3`".
    fn kept_rows(&self) -> String {
        let n = self.rows_on_disk;
        if n == 0 {
            return "no rows".to_string();
        }
        let fields = self
            .header
            .split(',')
            .zip(self.last_on_disk.split(','))
            .take(2)
            .map(|(h, v)| format!("{h} {v}"))
            .collect::<Vec<_>>()
            .join(", ");
        format!(
            "{n} complete row{}, the last with {fields}",
            if n == 1 { "" } else { "s" }
        )
    }
}

impl Drop for RowFile {
    fn drop(&mut self) {
        if self.failed.is_none() && !self.buf.is_empty() {
            let _ = self.flush_inner(false);
        }
    }
}

fn count_lines(b: &[u8]) -> u64 {
    b.iter().filter(|&&c| c == b'\n').count() as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    #[test]
    fn rows_stream_and_drop_flushes() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.csv");
        {
            let mut r = RowFile::create(&p, "step,time_s,x").unwrap();
            assert_eq!(std::fs::read_to_string(&p).unwrap(), "step,time_s,x\n");
            r.push(b"0,0.0,1").unwrap();
            r.flush().unwrap();
            r.push(b"1,0.5,2").unwrap();
            assert_eq!(r.rows(), 2);
        }
        assert_eq!(
            std::fs::read_to_string(&p).unwrap(),
            "step,time_s,x\n0,0.0,1\n1,0.5,2\n"
        );
    }

    /// A disk with `room` bytes left: a write past it is cut short, the next one fails with
    /// `ENOSPC`, as a full file system answers.
    struct FullDisk {
        data: Arc<Mutex<Vec<u8>>>,
        room: usize,
    }

    impl Write for FullDisk {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            let mut d = self.data.lock().unwrap();
            let n = b.len().min(self.room.saturating_sub(d.len()));
            if n == 0 && !b.is_empty() {
                return Err(std::io::Error::from_raw_os_error(28));
            }
            d.extend_from_slice(&b[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Sink for FullDisk {
        fn set_len(&mut self, len: u64) -> std::io::Result<()> {
            self.data.lock().unwrap().truncate(len as usize);
            Ok(())
        }
    }

    /// A write that fails part-way leaves the file at its last whole row, and the error
    /// names the file, the reason and the last row kept; later writes are refused, and
    /// dropping writes nothing more.
    #[test]
    fn measures_write_failure_keeps_whole_rows_and_says_which() {
        let data = Arc::new(Mutex::new(Vec::new()));
        let header = "step,time_s,x";
        let room = header.len() + 1 + 2 * 8 + 3;
        let disk = FullDisk {
            data: data.clone(),
            room,
        };
        let mut r =
            RowFile::with_sink(Path::new("out/measures.csv"), Box::new(disk), header).unwrap();
        r.push(b"0,0.0,1").unwrap();
        r.push(b"1,0.5,2").unwrap();
        r.push(b"2,1.0,3").unwrap();
        let e = r.flush().unwrap_err().to_string();
        assert!(e.starts_with("out/measures.csv: "), "{e}");
        assert!(e.contains("No space left on device"), "{e}");
        assert!(
            e.contains(
                "the file keeps its header and 2 complete rows, the last with step 1, time_s 0.5"
            ),
            "{e}"
        );
        assert!(e.contains("the partial row after them was cut off"), "{e}");
        let kept = "step,time_s,x\n0,0.0,1\n1,0.5,2\n";
        assert_eq!(String::from_utf8_lossy(&data.lock().unwrap()), kept);
        let again = r.push(b"3,1.5,4").unwrap_err().to_string();
        assert!(again.contains("an earlier write failed"), "{again}");
        drop(r);
        assert_eq!(String::from_utf8_lossy(&data.lock().unwrap()), kept);
    }

    /// A disk full before the first row: the header is kept, no row is claimed.
    #[test]
    fn a_write_failure_before_any_row_says_no_rows() {
        let data = Arc::new(Mutex::new(Vec::new()));
        let disk = FullDisk {
            data: data.clone(),
            room: 14 + 4,
        };
        let mut r =
            RowFile::with_sink(Path::new("m.csv"), Box::new(disk), "step,time_s,x").unwrap();
        r.push(b"0,0.0,1").unwrap();
        let e = r.flush().unwrap_err().to_string();
        assert!(e.contains("keeps its header and no rows"), "{e}");
        assert_eq!(
            String::from_utf8_lossy(&data.lock().unwrap()),
            "step,time_s,x\n"
        );
    }
}
