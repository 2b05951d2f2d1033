//! A store-only zip writer: enough for an FMU (a few files, a few megabytes), with no
//! compression library to depend on. Entries carry a fixed date (1980-01-01) so the same
//! inputs give the same bytes.

/// CRC-32 (IEEE 802.3, reflected, as zip uses).
pub fn crc32(data: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut t = [0u32; 256];
        for (i, slot) in t.iter_mut().enumerate() {
            let mut c = i as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
            *slot = c;
        }
        t
    });
    !data.iter().fold(!0u32, |c, &b| {
        table[((c ^ u32::from(b)) & 0xff) as usize] ^ (c >> 8)
    })
}

/// One file of the archive.
pub struct Entry {
    /// Path inside the archive, `/`-separated.
    pub name: String,
    /// Contents.
    pub data: Vec<u8>,
    /// Whether the file is executable (Unix mode 755 instead of 644).
    pub executable: bool,
}

/// Zip archive holding `entries` uncompressed; `None` when a file or the archive passes
/// the 4 GiB limit of plain zip.
pub fn store(entries: &[Entry]) -> Option<Vec<u8>> {
    const VERSION: u16 = 20;
    const UTF8_NAMES: u16 = 1 << 11;
    const DOS_DATE_1980_01_01: u16 = (1 << 5) | 1;
    let mut out = Vec::new();
    let mut central = Vec::new();
    let put16 = |v: &mut Vec<u8>, x: u16| v.extend_from_slice(&x.to_le_bytes());
    let put32 = |v: &mut Vec<u8>, x: u32| v.extend_from_slice(&x.to_le_bytes());
    for e in entries {
        let offset = u32::try_from(out.len()).ok()?;
        let size = u32::try_from(e.data.len()).ok()?;
        let name_len = u16::try_from(e.name.len()).ok()?;
        let crc = crc32(&e.data);
        // Local file header.
        put32(&mut out, 0x0403_4b50);
        put16(&mut out, VERSION);
        put16(&mut out, UTF8_NAMES);
        put16(&mut out, 0); // stored
        put16(&mut out, 0); // time 00:00
        put16(&mut out, DOS_DATE_1980_01_01);
        put32(&mut out, crc);
        put32(&mut out, size);
        put32(&mut out, size);
        put16(&mut out, name_len);
        put16(&mut out, 0);
        out.extend_from_slice(e.name.as_bytes());
        out.extend_from_slice(&e.data);
        // Central directory record; made on Unix so the mode bits count.
        let mode: u32 = if e.executable { 0o100_755 } else { 0o100_644 };
        put32(&mut central, 0x0201_4b50);
        put16(&mut central, (3 << 8) | VERSION);
        put16(&mut central, VERSION);
        put16(&mut central, UTF8_NAMES);
        put16(&mut central, 0);
        put16(&mut central, 0);
        put16(&mut central, DOS_DATE_1980_01_01);
        put32(&mut central, crc);
        put32(&mut central, size);
        put32(&mut central, size);
        put16(&mut central, name_len);
        put16(&mut central, 0); // extra
        put16(&mut central, 0); // comment
        put16(&mut central, 0); // disk
        put16(&mut central, 0); // internal attributes
        put32(&mut central, mode << 16);
        put32(&mut central, offset);
        central.extend_from_slice(e.name.as_bytes());
    }
    let cd_offset = u32::try_from(out.len()).ok()?;
    let cd_size = u32::try_from(central.len()).ok()?;
    let count = u16::try_from(entries.len()).ok()?;
    out.extend_from_slice(&central);
    put32(&mut out, 0x0605_4b50);
    put16(&mut out, 0);
    put16(&mut out, 0);
    put16(&mut out, count);
    put16(&mut out, count);
    put32(&mut out, cd_size);
    put32(&mut out, cd_offset);
    put16(&mut out, 0);
    u32::try_from(out.len()).ok()?;
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_check_value() {
        // The standard check value of CRC-32/ISO-HDLC.
        assert_eq!(crc32(b"123456789"), 0xcbf4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn archive_layout() {
        let z = store(&[
            Entry {
                name: "a.txt".into(),
                data: b"hello".to_vec(),
                executable: false,
            },
            Entry {
                name: "dir/b.bin".into(),
                data: vec![0, 1, 2],
                executable: true,
            },
        ])
        .unwrap_or_default();
        // First local header, its data stored as is, then the end record with 2 entries.
        assert_eq!(&z[..4], &[0x50, 0x4b, 3, 4]);
        assert_eq!(&z[30..35], b"a.txt");
        assert_eq!(&z[35..40], b"hello");
        let end = z.len() - 22;
        assert_eq!(&z[end..end + 4], &[0x50, 0x4b, 5, 6]);
        assert_eq!(u16::from_le_bytes([z[end + 10], z[end + 11]]), 2);
        let cd_offset = u32::from_le_bytes([z[end + 16], z[end + 17], z[end + 18], z[end + 19]]);
        assert_eq!(
            &z[cd_offset as usize..cd_offset as usize + 4],
            &[0x50, 0x4b, 1, 2]
        );
    }
}
