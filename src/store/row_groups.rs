//! How a job's per-block rows (and per-step samples) are laid out in storage: consecutive
//! rows framed together and compressed with zstd, one database row per group of about
//! 512 KiB of JSON. A 100k-block simulate result is then ~190 database rows and ~14 MB to
//! write durably instead of 100k rows and 100 MB, which is what its commit time was (the
//! server's own COPY of the 100 MB took 1.2–2.4 s on a 2-core VM). Reads decompress only the
//! groups a page needs.
//!
//! A group's raw bytes are, for each row in seq order: the seq (i64 LE), the JSON's length
//! (u32 LE), the JSON. Rows stored one by one before groups existed were migrated as groups
//! of one, their JSON as it was (codec `row`).

use rayon::prelude::*;

/// Raw bytes at which a group is closed (it may pass it by one row).
const GROUP_RAW_BYTES: usize = 512 << 10;
/// Rows at which a group is closed: a page read decodes at most this many rows it does not need.
const GROUP_MAX_ROWS: usize = 4096;
/// zstd level 1: 7x on simulate rows at ~400 MB/s a core; level 3 compressed them no
/// smaller here and at two thirds of the speed.
const ZSTD_LEVEL: i32 = 1;
/// Frame bytes before each row's JSON: seq and length.
const FRAME: usize = 12;

/// One stored group: rows `first_seq..=last_seq` (seqs need not be contiguous).
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    pub first_seq: i64,
    pub last_seq: i64,
    pub codec: &'static str,
    /// Length of the decompressed bytes, so that reading allocates exactly that.
    pub raw_bytes: i64,
    pub data: Vec<u8>,
}

/// Splits rows (in increasing seq order) into groups and compresses them, the groups in
/// parallel. CPU-bound: call from a blocking thread.
pub fn pack<S: AsRef<str> + Sync>(rows: &[(i64, S)]) -> std::io::Result<Vec<Group>> {
    let mut bounds = Vec::new();
    let (mut start, mut bytes) = (0, 0);
    for (i, (_, json)) in rows.iter().enumerate() {
        bytes += FRAME + json.as_ref().len();
        if bytes >= GROUP_RAW_BYTES || i + 1 - start >= GROUP_MAX_ROWS {
            bounds.push(start..i + 1);
            (start, bytes) = (i + 1, 0);
        }
    }
    if start < rows.len() {
        bounds.push(start..rows.len());
    }
    bounds
        .into_par_iter()
        .map(|range| {
            let rows = &rows[range];
            let mut raw = Vec::with_capacity(
                rows.iter()
                    .map(|(_, j)| FRAME + j.as_ref().len())
                    .sum::<usize>(),
            );
            for (seq, json) in rows {
                let json = json.as_ref().as_bytes();
                let len = u32::try_from(json.len())
                    .map_err(|_| std::io::Error::other("a result row over 4 GiB"))?;
                raw.extend_from_slice(&seq.to_le_bytes());
                raw.extend_from_slice(&len.to_le_bytes());
                raw.extend_from_slice(json);
            }
            Ok(Group {
                first_seq: rows[0].0,
                last_seq: rows[rows.len() - 1].0,
                codec: "zstd",
                raw_bytes: raw.len() as i64,
                data: zstd::bulk::compress(&raw, ZSTD_LEVEL)?,
            })
        })
        .collect()
}

/// The rows of one stored group, in seq order. A group that does not decode as it says is
/// an error (storage corruption), never a panic or an allocation its header did not state.
pub fn unpack(
    codec: &str,
    first_seq: i64,
    raw_bytes: i64,
    data: Vec<u8>,
) -> std::io::Result<Vec<(i64, String)>> {
    let corrupt = |what: &str| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("result row group at seq {first_seq}: {what}"),
        )
    };
    match codec {
        "row" => {
            let json = String::from_utf8(data).map_err(|_| corrupt("not UTF-8"))?;
            Ok(vec![(first_seq, json)])
        }
        "zstd" => {
            let capacity = usize::try_from(raw_bytes).map_err(|_| corrupt("negative size"))?;
            let raw = zstd::bulk::decompress(&data, capacity)?;
            if raw.len() != capacity {
                return Err(corrupt("decompressed size differs from the stored one"));
            }
            let mut rows = Vec::new();
            let mut at = 0;
            while at < raw.len() {
                let head = raw
                    .get(at..at + FRAME)
                    .ok_or_else(|| corrupt("cut frame"))?;
                let seq = i64::from_le_bytes(head[..8].try_into().expect("8 bytes"));
                let len = u32::from_le_bytes(head[8..].try_into().expect("4 bytes")) as usize;
                let json = raw
                    .get(at + FRAME..at + FRAME + len)
                    .ok_or_else(|| corrupt("cut row"))?;
                let json = std::str::from_utf8(json).map_err(|_| corrupt("not UTF-8"))?;
                rows.push((seq, json.to_owned()));
                at += FRAME + len;
            }
            Ok(rows)
        }
        other => Err(corrupt(&format!("unknown codec `{other}`"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(n: usize, width: usize) -> Vec<(i64, String)> {
        (0..n)
            .map(|i| {
                let seq = (i * 3) as i64; // not contiguous, like samples
                (
                    seq,
                    format!(
                        "{{\"block\":{seq},\"é\":\"{}\"}}",
                        "x".repeat(width + i % 7)
                    ),
                )
            })
            .collect()
    }

    #[test]
    fn groups_give_back_every_row_in_order() {
        for (n, width) in [(0, 10), (1, 10), (5000, 300), (3, 2_000_000)] {
            let rows = rows(n, width);
            let groups = pack(&rows).unwrap();
            let mut back = Vec::new();
            for g in &groups {
                assert!(g.first_seq <= g.last_seq);
                back.extend(unpack(g.codec, g.first_seq, g.raw_bytes, g.data.clone()).unwrap());
            }
            assert_eq!(back, rows, "{n} rows of {width}");
            // Groups are closed by size and by count, and follow each other.
            for w in groups.windows(2) {
                assert!(w[0].last_seq < w[1].first_seq);
            }
            if n == 5000 {
                assert!(groups.len() >= 3, "{} groups", groups.len());
                assert!(groups
                    .iter()
                    .all(|g| g.raw_bytes as usize <= GROUP_RAW_BYTES + 400));
            }
            if width == 2_000_000 {
                assert_eq!(
                    groups.len(),
                    3,
                    "a row over the group size is a group of its own"
                );
            }
        }
    }

    #[test]
    fn a_group_of_short_rows_is_closed_by_count() {
        let rows: Vec<(i64, String)> = (0..10_000).map(|i| (i, "{}".to_string())).collect();
        let groups = pack(&rows).unwrap();
        assert_eq!(groups.len(), 3);
        assert_eq!(groups[0].last_seq, GROUP_MAX_ROWS as i64 - 1);
    }

    #[test]
    fn a_migrated_row_reads_as_it_was() {
        let back = unpack("row", 7, 9, b"{\"a\":1}".to_vec()).unwrap();
        assert_eq!(back, vec![(7, "{\"a\":1}".to_string())]);
    }

    #[test]
    fn a_corrupt_group_is_an_error_not_a_panic() {
        let g = pack(&rows(50, 40)).unwrap().remove(0);
        // Stated size too small, too large, negative; data cut; data garbled; codec unknown.
        for (raw, data) in [
            (g.raw_bytes - 1, g.data.clone()),
            (g.raw_bytes + 1, g.data.clone()),
            (-1, g.data.clone()),
            (g.raw_bytes, g.data[..g.data.len() / 2].to_vec()),
            (g.raw_bytes, vec![0x28, 0xb5, 0x2f, 0xfd, 1, 2, 3]),
        ] {
            assert!(unpack("zstd", 0, raw, data).is_err());
        }
        assert!(unpack("lz4", 0, g.raw_bytes, g.data.clone()).is_err());
        assert!(unpack("row", 0, 2, vec![0xff, 0xfe]).is_err());
        // Frames that overrun the bytes: a length pointing past the end.
        let mut raw = 5i64.to_le_bytes().to_vec();
        raw.extend_from_slice(&1000u32.to_le_bytes());
        raw.extend_from_slice(b"{}");
        let data = zstd::bulk::compress(&raw, 1).unwrap();
        assert!(unpack("zstd", 5, raw.len() as i64, data).is_err());
    }
}
