//! The resume key of a job: one 64-bit FNV-1a hash of the meshmatch binary (version, size and
//! modification time), the job's arguments and the content of every input file. A job whose
//! outputs all exist and whose key equals the one recorded by its last successful run is skipped.

use std::io::Read;
use std::path::Path;

use super::jobfile::Job;

/// FNV-1a, 64 bits: stable across builds and platforms, which the key must be.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// A field followed by a separator, so ("ab", "c") and ("a", "bc") differ.
    fn field(&mut self, bytes: &[u8]) {
        self.write(bytes);
        self.write(&[0xff]);
    }
}

/// What identifies the running binary: its version, and the size and modification time of the
/// executable (a rebuilt binary reruns every job).
pub fn binary_id(exe: &Path) -> String {
    let meta = std::fs::metadata(exe).ok();
    let size = meta.as_ref().map_or(0, |m| m.len());
    let mtime = meta
        .and_then(|m| m.modified().ok())
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    format!("{} {size} {mtime}", env!("CARGO_PKG_VERSION"))
}

/// The key of `job` run by the binary `binary` in the job folder `dir`, as 16 hex digits;
/// `None` when an input cannot be read.
pub fn job_key(job: &Job, binary: &str, dir: &Path) -> Option<String> {
    let mut h = Fnv::new();
    h.field(b"meshmatch-batch-1");
    h.field(binary.as_bytes());
    for a in &job.args {
        h.field(a.as_bytes());
    }
    for input in &job.inputs {
        h.field(input.to_string_lossy().as_bytes());
        let mut file = std::fs::File::open(dir.join(input)).ok()?;
        let mut buf = vec![0u8; 1 << 20];
        loop {
            let n = file.read(&mut buf).ok()?;
            if n == 0 {
                break;
            }
            h.write(&buf[..n]);
        }
        h.write(&[0xff]);
    }
    Some(format!("{:016x}", h.0))
}

/// True when every output of `job` exists (a job without outputs never counts as done).
pub fn outputs_exist(job: &Job, dir: &Path) -> bool {
    !job.outputs.is_empty() && job.outputs.iter().all(|o| dir.join(o).exists())
}
