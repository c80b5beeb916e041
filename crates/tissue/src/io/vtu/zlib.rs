//! VTK's zlib-compressed binary arrays (`compressor="vtkZLibDataCompressor"`).
//!
//! Layout: a header of unsigned integers `[nblocks, block size, last block size, compressed
//! size of each block...]` (UInt32 or UInt64 per `header_type`), then the zlib streams of the
//! blocks one after another. Every block but the last holds `block size` bytes once inflated;
//! the last holds `last block size` bytes, or a full block when that is 0.

use std::borrow::Cow;
use std::io::Read;

use flate2::read::ZlibDecoder;

use super::decode_uint;

/// Deflate cannot expand data more than ~1032:1, so a block claiming more is corrupt; the
/// slack covers the zlib header and checksum of tiny blocks.
const MAX_RATIO: u64 = 1032;
const SLACK: u64 = 64;

/// Inflates one compressed array whose header starts at `raw[0]` (bytes after the array are
/// ignored). Errors carry the byte of `raw` at fault and a message.
pub(super) fn inflate(
    raw: &[u8],
    hsize: usize,
    big: bool,
) -> Result<Cow<'static, [u8]>, (usize, String)> {
    let word = |i: usize| -> Option<u64> {
        let at = i.checked_mul(hsize)?;
        raw.get(at..at.checked_add(hsize)?)
            .map(|b| decode_uint(b, big))
    };
    let (Some(nblocks), Some(block), Some(last)) = (word(0), word(1), word(2)) else {
        return Err((
            0,
            format!(
                "the compression header needs {} bytes but only {} are there",
                3 * hsize,
                raw.len()
            ),
        ));
    };
    // Check the block count against the bytes present before trusting it for anything.
    let header_len = usize::try_from(nblocks)
        .ok()
        .and_then(|n| n.checked_add(3)?.checked_mul(hsize))
        .filter(|&h| h <= raw.len());
    let Some(header_len) = header_len else {
        return Err((
            0,
            format!(
                "the compression header claims {nblocks} blocks, more than the {} bytes that follow can describe",
                raw.len()
            ),
        ));
    };
    let nblocks = nblocks as usize;
    if last > block {
        return Err((
            2 * hsize,
            format!("the last block ({last} bytes) is larger than a block ({block} bytes)"),
        ));
    }
    let mut out = Vec::new();
    let mut at = header_len;
    for i in 0..nblocks {
        let csize = word(3 + i).unwrap_or(0);
        let want = if i + 1 == nblocks && last != 0 {
            last
        } else {
            block
        };
        let stream = usize::try_from(csize)
            .ok()
            .and_then(|c| raw.get(at..at.checked_add(c)?));
        let Some(stream) = stream else {
            return Err((
                (3 + i) * hsize,
                format!(
                    "block {i} is {csize} compressed bytes but only {} are left",
                    raw.len().saturating_sub(at)
                ),
            ));
        };
        if want > csize.saturating_mul(MAX_RATIO).saturating_add(SLACK) {
            return Err((
                at,
                format!(
                    "block {i} claims {want} bytes from {csize} compressed bytes, more than zlib can hold"
                ),
            ));
        }
        // Output grows only with what the stream really yields, never with the claim.
        let before = out.len();
        let mut decoder = ZlibDecoder::new(stream).take(want.saturating_add(1));
        decoder
            .read_to_end(&mut out)
            .map_err(|e| (at, format!("block {i} is not valid zlib data: {e}")))?;
        let got = out.len() - before;
        if got as u64 != want {
            return Err((
                at,
                format!("block {i} inflates to {got} bytes, but the header says {want}"),
            ));
        }
        at += stream.len();
    }
    Ok(Cow::Owned(out))
}
