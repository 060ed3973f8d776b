//! LCM event logs (the files `lcm-logger` writes and `lcm-logplayer` replays), through liblcm's
//! eventlog API.

use std::ffi::CString;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::ptr::NonNull;

use crate::error::{Error, Result};

/// One event of a log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogEvent {
    /// Event number in the log (0, 1, 2, …).
    pub number: i64,
    /// Receive time, µs since the Unix epoch.
    pub timestamp: i64,
    /// The channel.
    pub channel: String,
    /// The message bytes (fingerprint included).
    pub data: Vec<u8>,
}

struct Handle {
    ptr: NonNull<lcm_sys::lcm_eventlog_t>,
    path: PathBuf,
}

// SAFETY: an eventlog is a FILE* plus a counter, used through &mut only.
unsafe impl Send for Handle {}

impl Handle {
    fn open(path: &Path, mode: &'static str) -> Result<Handle> {
        let open_err = |cause| Error::LogOpen {
            path: path.to_owned(),
            mode,
            cause,
        };
        let cpath = CString::new(path.as_os_str().as_bytes()).map_err(|_| {
            open_err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "path contains a NUL byte",
            ))
        })?;
        let cmode = CString::new(mode).expect("static mode");
        // SAFETY: both are valid C strings; the mode is one of r, w, a (others assert in C).
        let ptr = unsafe { lcm_sys::lcm_eventlog_create(cpath.as_ptr(), cmode.as_ptr()) };
        match NonNull::new(ptr) {
            Some(ptr) => Ok(Handle {
                ptr,
                path: path.to_owned(),
            }),
            None => Err(open_err(std::io::Error::last_os_error())),
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: created by lcm_eventlog_create, destroyed once.
        unsafe { lcm_sys::lcm_eventlog_destroy(self.ptr.as_ptr()) }
    }
}

/// Reads an LCM log file event by event. Iterating yields events until the end of the file.
///
/// liblcm's reader skips garbage between events and stops at a truncated event.
pub struct LogReader {
    h: Handle,
}

impl std::fmt::Debug for LogReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LogReader")
            .field("path", &self.h.path)
            .finish()
    }
}

impl LogReader {
    /// Opens a log for reading.
    pub fn open(path: impl AsRef<Path>) -> Result<LogReader> {
        Ok(LogReader {
            h: Handle::open(path.as_ref(), "r")?,
        })
    }

    /// The next event, or `None` at the end of the log.
    pub fn read_event(&mut self) -> Option<LogEvent> {
        // SAFETY: the handle is live; the returned event is freed below.
        let ev = unsafe { lcm_sys::lcm_eventlog_read_next_event(self.h.ptr.as_ptr()) };
        let ev = NonNull::new(ev)?;
        // SAFETY: liblcm returns channellen channel bytes and datalen data bytes.
        let out = unsafe {
            let e = ev.as_ref();
            let channel = if e.channel.is_null() || e.channellen <= 0 {
                &[][..]
            } else {
                std::slice::from_raw_parts(e.channel as *const u8, e.channellen as usize)
            };
            let data = if e.data.is_null() || e.datalen <= 0 {
                &[][..]
            } else {
                std::slice::from_raw_parts(e.data as *const u8, e.datalen as usize)
            };
            LogEvent {
                number: e.eventnum,
                timestamp: e.timestamp,
                channel: String::from_utf8_lossy(channel).into_owned(),
                data: data.to_vec(),
            }
        };
        // SAFETY: returned by lcm_eventlog_read_next_event, freed once.
        unsafe { lcm_sys::lcm_eventlog_free_event(ev.as_ptr()) };
        Some(out)
    }

    /// Moves to (about) the first event at or after `timestamp` µs.
    pub fn seek_to_timestamp(&mut self, timestamp: i64) -> Result<()> {
        // SAFETY: the handle is live.
        let rc = unsafe { lcm_sys::lcm_eventlog_seek_to_timestamp(self.h.ptr.as_ptr(), timestamp) };
        if rc == 0 {
            Ok(())
        } else {
            Err(Error::LogSeek {
                path: self.h.path.clone(),
                timestamp,
            })
        }
    }
}

impl Iterator for LogReader {
    type Item = LogEvent;
    fn next(&mut self) -> Option<LogEvent> {
        self.read_event()
    }
}

/// Writes an LCM log file that `lcm-logplayer` and `lcm-spy` can read.
pub struct LogWriter {
    h: Handle,
}

impl std::fmt::Debug for LogWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LogWriter")
            .field("path", &self.h.path)
            .finish()
    }
}

impl LogWriter {
    /// Creates (or truncates) a log file.
    pub fn create(path: impl AsRef<Path>) -> Result<LogWriter> {
        Ok(LogWriter {
            h: Handle::open(path.as_ref(), "w")?,
        })
    }

    /// Opens a log file for appending.
    pub fn append(path: impl AsRef<Path>) -> Result<LogWriter> {
        Ok(LogWriter {
            h: Handle::open(path.as_ref(), "a")?,
        })
    }

    /// Appends one event; liblcm numbers it. Returns the event number given.
    pub fn write(&mut self, timestamp: i64, channel: &str, data: &[u8]) -> Result<i64> {
        let err = || Error::LogWrite {
            path: self.h.path.clone(),
        };
        let channellen = i32::try_from(channel.len()).map_err(|_| err())?;
        let datalen = i32::try_from(data.len()).map_err(|_| err())?;
        let mut ev = lcm_sys::lcm_eventlog_event_t {
            eventnum: 0,
            timestamp,
            channellen,
            datalen,
            channel: channel.as_ptr() as *mut _,
            data: data.as_ptr() as *mut _,
        };
        // SAFETY: liblcm only reads the channel and data buffers (fwrite).
        let rc = unsafe { lcm_sys::lcm_eventlog_write_event(self.h.ptr.as_ptr(), &mut ev) };
        if rc == 0 {
            Ok(ev.eventnum)
        } else {
            Err(err())
        }
    }

    /// Flushes buffered events to the file.
    pub fn flush(&mut self) -> Result<()> {
        // SAFETY: `f` is the FILE* liblcm opened.
        let rc = unsafe { libc::fflush(self.h.ptr.as_ref().f as *mut libc::FILE) };
        if rc == 0 {
            Ok(())
        } else {
            Err(Error::LogWrite {
                path: self.h.path.clone(),
            })
        }
    }
}

/// Runs `f` with this process's stderr going to a temporary file, and returns what was
/// written there, line by line. liblcm's log reader prints its complaints about a log's bytes
/// ("Log event has invalid data length", "Invalid header after log data") on stderr,
/// unprefixed: a tool that reads a log takes them and says them as its own. Meant for a tool's
/// single reading thread: whatever any other thread writes to stderr meanwhile is taken too.
pub fn capturing_stderr<T>(f: impl FnOnce() -> T) -> std::io::Result<(T, Vec<String>)> {
    use std::io::{Read, Seek};
    use std::os::fd::AsRawFd;
    let dir = std::env::temp_dir();
    let path = dir.join(format!(
        ".stderr-{}-{:x}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos())
    ));
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .open(&path)?;
    let _ = std::fs::remove_file(&path);
    // SAFETY: plain descriptor calls; fd 2 is given back before returning.
    let saved = unsafe { libc::dup(2) };
    if saved < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: as above.
    if unsafe { libc::dup2(file.as_raw_fd(), 2) } < 0 {
        let e = std::io::Error::last_os_error();
        // SAFETY: closing the copy made above.
        unsafe { libc::close(saved) };
        return Err(e);
    }
    let out = f();
    // SAFETY: C's buffered streams flushed, then fd 2 given back and the copy closed.
    unsafe {
        libc::fflush(std::ptr::null_mut());
        libc::dup2(saved, 2);
        libc::close(saved);
    }
    let mut text = String::new();
    file.rewind()?;
    file.read_to_string(&mut text)?;
    Ok((
        out,
        text.lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .map(str::to_owned)
            .collect(),
    ))
}

/// The bytes an event takes in a log file: its header (sync word, number, time, lengths) and
/// its channel and data.
pub fn event_size(e: &LogEvent) -> u64 {
    28 + e.channel.len() as u64 + e.data.len() as u64
}
