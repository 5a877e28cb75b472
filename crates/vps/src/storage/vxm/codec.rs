//! The codec of a `.vxm` brick payload, byte for byte as in `docs/FORMAT.md`: the previous-voxel
//! predictor, zigzagged distance residuals (codec 4's, predicted by a median, in `median.rs`),
//! and zstd frames without their magic number.

use crate::grid::BRICK_VOXELS;
use crate::voxmap::{
    bound_outer_distances, distance_is_read, distance_on_its_side, far_distance, outer_distance, BrickDistances,
    BrickValues, StoredBrick,
};

use super::dictionary::Dictionary;
use super::format::{
    CODEC_DIAGONAL_RANS, CODEC_ZSTD_DELTA_DISTANCE, CODEC_ZSTD_DELTA_READ_DISTANCE, CODEC_ZSTD_MEDIAN_DICTIONARY,
    CODEC_ZSTD_MEDIAN_DISTANCE, CODEC_ZSTD_MEDIAN_ROWS, MAX_PAYLOAD_BYTES, MAX_PAYLOAD_BYTES_DISTANCE,
    MAX_PAYLOAD_BYTES_MEDIAN,
};
use super::median;
pub use super::median::Predictor;
use super::rans::Tables;
use super::{diagonal, rans};
use rayon::prelude::*;

/// zstd level used by the writer. Writing is on the critical path of generation: on the
/// Nefertiti scan voxelized into a 3.4·10⁸-voxel grid (65,106 stored bricks), level 1 wrote
/// the file in 0.30–0.37 s at 0.25 bytes per stored voxel, level 3 in 0.65–0.70 s at 0.22 and
/// level 5 in 0.88–0.92 s at 0.18. Every level is far below the 1 byte per voxel target, so
/// the fastest wins; decompression speed is the same. Readers accept any level.
pub const ZSTD_LEVEL: i32 = 1;

/// Bytes a codec-2 frame decompresses to: 512 value residuals, then the 512 low bytes and the
/// 512 high bytes of the distance residuals. A codec-3 frame holds at most as many.
const DISTANCE_FRAME_BYTES: usize = 3 * BRICK_VOXELS;

/// The magic number that starts a zstd frame; payloads store frames without it.
const ZSTD_FRAME_MAGIC: [u8; 4] = 0xFD2F_B528u32.to_le_bytes();

/// Apply the "previous voxel" predictor: each value minus the voxel before it along x, or
/// for the first of a row the one below it along y, or for the first of a slice the one
/// below along z. Layer values change by at most one between neighbours, so the residuals
/// are mostly -1, 0, 1, and zstd packs them 10–25 % tighter than the raw values (measured on
/// layered balls with 3 to 20 layers).
fn predict(values: &BrickValues) -> [u8; BRICK_VOXELS] {
    let mut out = [0u8; BRICK_VOXELS];
    for (i, o) in out.iter_mut().enumerate() {
        *o = values[i].wrapping_sub(prediction(values, i)) as u8;
    }
    out
}

/// Undo [`predict`] (and the distances' prediction) from the residuals: a running sum along
/// each row, started from the row's own prediction. Written per row, rather than through
/// [`prediction`], because lookups run it on every brick they read (through [`prediction`],
/// the distances took a quarter of a brick's decoding, measured).
fn unpredict<T: WrappingSum>(residuals: &[T; BRICK_VOXELS]) -> [T; BRICK_VOXELS] {
    let mut values = [T::default(); BRICK_VOXELS];
    for row in 0..BRICK_VOXELS / 8 {
        let start = row * 8;
        let mut acc = if row % 8 != 0 {
            values[start - 8]
        } else if row != 0 {
            values[start - 64]
        } else {
            T::default()
        };
        for x in start..start + 8 {
            acc = acc.plus(residuals[x]);
            values[x] = acc;
        }
    }
    values
}

/// The integers of a brick's values (`i8`) and distances (`i16`), summed wrapping.
trait WrappingSum: Copy + Default {
    fn plus(self, r: Self) -> Self;
}

impl WrappingSum for i8 {
    #[inline(always)]
    fn plus(self, r: i8) -> i8 {
        self.wrapping_add(r)
    }
}

impl WrappingSum for i16 {
    #[inline(always)]
    fn plus(self, r: i16) -> i16 {
        self.wrapping_add(r)
    }
}

/// The "previous voxel" prediction of entry `i` of a brick's values or distances from those
/// before it: the voxel before along x, or for the first of a row the one below in y, or for
/// the first of a slice the one below in z; 0 for the first.
#[inline]
fn prediction<T: Copy + Default>(values: &[T; BRICK_VOXELS], i: usize) -> T {
    if i & 7 != 0 {
        values[i - 1]
    } else if i & 63 != 0 {
        values[i - 8]
    } else if i != 0 {
        values[i - 64]
    } else {
        T::default()
    }
}

/// Compress `raw` into a payload of at most `max` bytes: a zstd frame without its magic.
fn payload_of(compressor: &mut zstd::bulk::Compressor<'_>, raw: &[u8], max: usize) -> std::io::Result<Vec<u8>> {
    let frame = compressor.compress(raw)?;
    match frame.strip_prefix(&ZSTD_FRAME_MAGIC[..]) {
        Some(rest) if rest.len() <= max => Ok(rest.to_vec()),
        _ => Err(std::io::Error::other("zstd produced an unexpected frame")),
    }
}

/// Compress one brick into its payload.
pub fn encode_brick(compressor: &mut zstd::bulk::Compressor<'_>, values: &BrickValues) -> std::io::Result<Vec<u8>> {
    payload_of(compressor, &predict(values), MAX_PAYLOAD_BYTES)
}

/// `0, -1, 1, -2, 2, …` to `0, 1, 2, 3, 4, …`: small magnitudes to small numbers.
#[inline]
pub(super) fn zigzag(r: i16) -> u16 {
    ((r << 1) ^ (r >> 15)) as u16
}

/// The inverse of [`zigzag`].
#[inline]
pub(super) fn unzigzag(z: u16) -> i16 {
    ((z >> 1) as i16) ^ -((z & 1) as i16)
}

/// Compress one brick with its distances into a codec-2 payload.
pub fn encode_brick_with_distances(
    compressor: &mut zstd::bulk::Compressor<'_>,
    values: &BrickValues,
    distances: &BrickDistances,
) -> std::io::Result<Vec<u8>> {
    let mut raw = [0u8; DISTANCE_FRAME_BYTES];
    raw[..BRICK_VOXELS].copy_from_slice(&predict(values));
    // Distances are predicted as values are, the previous voxel's: measured on Nefertiti
    // (voxels of 0.5225, 5 layers, 65,106 bricks, steps of 1/32), 15.79 MB with it, 15.90 with
    // the plane through three neighbours in the same slice, 16.54 with the line through the
    // two before along x.
    for i in 0..BRICK_VOXELS {
        let r = zigzag(distances[i].wrapping_sub(prediction(distances, i)));
        // Low bytes and high bytes apart: zigzagged, small residuals of either sign have a
        // high byte of 0.
        raw[BRICK_VOXELS + i] = r as u8;
        raw[2 * BRICK_VOXELS + i] = (r >> 8) as u8;
    }
    payload_of(compressor, &raw, MAX_PAYLOAD_BYTES_DISTANCE)
}

/// Compress one brick with its distances into a codec-3 payload: the value residuals, then
/// the low and the high bytes of the distance residuals of the voxels a contact reads
/// ([`distance_is_read`]), in index order. The others are predicted from, and decode to,
/// their [`outer_distance`], whatever `distances` holds for them.
pub fn encode_brick_with_read_distances(
    compressor: &mut zstd::bulk::Compressor<'_>,
    values: &BrickValues,
    distances: &BrickDistances,
) -> std::io::Result<Vec<u8>> {
    let mut d = *distances;
    bound_outer_distances(values, &mut d);
    let mut raw = Vec::with_capacity(DISTANCE_FRAME_BYTES);
    raw.extend_from_slice(&predict(values));
    let residuals: Vec<u16> = (0..BRICK_VOXELS)
        .filter(|&i| distance_is_read(values[i]))
        .map(|i| zigzag(d[i].wrapping_sub(prediction(&d, i))))
        .collect();
    raw.extend(residuals.iter().map(|&r| r as u8));
    raw.extend(residuals.iter().map(|&r| (r >> 8) as u8));
    payload_of(compressor, &raw, MAX_PAYLOAD_BYTES_DISTANCE)
}

/// Bytes a codec-4 frame decompresses to at most: 512 value residuals and three bytes for each
/// distance residual past an escape.
const MEDIAN_FRAME_BYTES: usize = 4 * BRICK_VOXELS;

/// Compress one brick with its distances into a codec-4 payload: the value residuals, then
/// the residual stream of the distances of the voxels a contact reads ([`distance_is_read`])
/// against the median predictor (`median.rs`). The others are neither stored nor predicted
/// from, and decode to their [`outer_distance`], whatever `distances` holds for them.
pub fn encode_brick_with_median_distances(
    compressor: &mut zstd::bulk::Compressor<'_>,
    values: &BrickValues,
    distances: &BrickDistances,
) -> std::io::Result<Vec<u8>> {
    compress_frame(compressor, &median_frame_of(Predictor::Nine, values, distances)?)
}

/// The frame of codec 6 before compression: the value residuals, then the residual stream of
/// the distances against [`Predictor::Rows`] (`median.rs`).
pub fn median_frame(values: &BrickValues, distances: &BrickDistances) -> std::io::Result<Vec<u8>> {
    median_frame_of(Predictor::Rows, values, distances)
}

/// The frame of codecs 4 and 5 ([`Predictor::Nine`]) or 6 ([`Predictor::Rows`]) before
/// compression.
pub fn median_frame_of(
    predictor: Predictor,
    values: &BrickValues,
    distances: &BrickDistances,
) -> std::io::Result<Vec<u8>> {
    let mut raw = Vec::with_capacity(2 * BRICK_VOXELS);
    raw.extend_from_slice(&predict(values));
    median::encode(values, distances, predictor, &mut raw)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))?;
    Ok(raw)
}

/// Compress a [`median_frame_of`] into a payload of codec 4, or of codec 5 or 6 with a
/// compressor made by [`new_compressor_with`] the file's dictionary.
pub fn compress_frame(compressor: &mut zstd::bulk::Compressor<'_>, frame: &[u8]) -> std::io::Result<Vec<u8>> {
    payload_of(compressor, frame, MAX_PAYLOAD_BYTES_MEDIAN)
}

/// Compress one brick with its distances into a codec-7 payload: its values frame (the value
/// residuals of codec 1, [`values_frame`], which the writer has made already to train on) in
/// a zstd frame (with the file's dictionary, if `compressor` has it), then the stream of the
/// distances a contact reads ([`distance_is_read`]) coded with `tables` (`diagonal.rs`). The
/// others are not stored and decode to their [`outer_distance`].
pub fn encode_brick_diagonal(
    compressor: &mut zstd::bulk::Compressor<'_>,
    frame: &[u8; BRICK_VOXELS],
    values: &BrickValues,
    distances: &BrickDistances,
    tables: &Tables,
) -> std::io::Result<Vec<u8>> {
    let mut payload = payload_of(compressor, frame, MAX_PAYLOAD_BYTES)?;
    diagonal::encode(values, distances, tables, &mut payload);
    if payload.len() > MAX_PAYLOAD_BYTES_MEDIAN {
        return Err(std::io::Error::other(format!(
            "a codec 7 payload of {} bytes, over the limit of {MAX_PAYLOAD_BYTES_MEDIAN}",
            payload.len()
        )));
    }
    Ok(payload)
}

/// The value residuals of codec 1 for a brick of `values`: the frame the writer trains a
/// version 7 file's zstd dictionary on.
pub fn values_frame(values: &BrickValues) -> [u8; BRICK_VOXELS] {
    predict(values)
}

/// Add the distance symbols of a brick to `counts`, which the writer fits a version 7 file's
/// rANS tables to.
pub fn count_distance_symbols(values: &BrickValues, distances: &BrickDistances, counts: &mut rans::Counts) {
    diagonal::count(values, distances, counts);
}

/// [`compress_frame`] for each of `frames` in parallel, one compressor a thread, with the
/// file's `dictionary` if it has one: the payloads in the frames' order.
pub(super) fn compress_frames<F: AsRef<[u8]> + Sync>(
    frames: &[F],
    dictionary: Option<&zstd::dict::EncoderDictionary<'_>>,
) -> Vec<std::io::Result<Vec<u8>>> {
    frames
        .par_iter()
        .map_init(
            || new_compressor_for(dictionary),
            |c, frame| {
                let c = c.as_mut().map_err(|e| std::io::Error::new(e.kind(), e.to_string()))?;
                compress_frame(c, frame.as_ref())
            },
        )
        .collect()
}

/// A zstd compressor set up as the writer uses it.
pub fn new_compressor() -> std::io::Result<zstd::bulk::Compressor<'static>> {
    set_up(zstd::bulk::Compressor::new(ZSTD_LEVEL)?)
}

/// [`new_compressor`] with a dictionary prepared at [`ZSTD_LEVEL`], for codecs 5 and 6.
pub fn new_compressor_with<'a>(
    dictionary: &'a zstd::dict::EncoderDictionary<'_>,
) -> std::io::Result<zstd::bulk::Compressor<'a>> {
    set_up(zstd::bulk::Compressor::with_prepared_dictionary(dictionary)?)
}

/// A compressor for the frames of codecs 5 and 6: with the file's dictionary, if it has one.
pub fn new_compressor_for<'a>(
    dictionary: Option<&'a zstd::dict::EncoderDictionary<'_>>,
) -> std::io::Result<zstd::bulk::Compressor<'a>> {
    match dictionary {
        Some(d) => new_compressor_with(d),
        None => new_compressor(),
    }
}

fn set_up(mut c: zstd::bulk::Compressor<'_>) -> std::io::Result<zstd::bulk::Compressor<'_>> {
    // The index holds a CRC per payload, so zstd's own checksum would only cost bytes; a
    // file has one dictionary, so its id would too.
    c.include_checksum(false)?;
    c.include_dictid(false)?;
    // The content size lets zstd reject a frame that claims other than 512 bytes early.
    c.include_contentsize(true)?;
    Ok(c)
}

/// Per-thread decompression state: creating a zstd context costs more than decompressing
/// a brick, and the frame buffer is where a payload gets its magic number back.
struct DecodeState {
    zstd: zstd::zstd_safe::DCtx<'static>,
    frame: Vec<u8>,
}

thread_local! {
    static DECODER: std::cell::RefCell<Option<DecodeState>> = const { std::cell::RefCell::new(None) };
}

/// Why a payload did not decode to a valid brick.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// The payload is not a zstd frame of the codec's length (or is too long to be one), or a
    /// distance lies beyond the reach.
    #[error("{0}")]
    Malformed(String),
    /// The payload decodes, but one value is outside `[-(layers+1), layers+1]`.
    #[error("voxel {voxel} has value {value} outside [-{limit}, {limit}]")]
    ValueOutOfRange {
        /// Local index of the first such voxel.
        voxel: usize,
        /// Its value.
        value: i8,
        /// `layers + 1`, the largest magnitude allowed.
        limit: i16,
    },
}

/// Decompress `payload` (a frame without its magic) into `out`, which it must fill exactly.
fn decompress(payload: &[u8], out: &mut [u8], max: usize) -> Result<(), DecodeError> {
    let (n, _) = decompress_into(payload, out, max, None, true)?;
    if n != out.len() {
        return Err(DecodeError::Malformed(format!(
            "decompressed to {n} bytes instead of {}",
            out.len()
        )));
    }
    Ok(())
}

/// Decompress `payload`, a frame without its magic (the whole payload if `whole`, else its
/// start), into the start of `out`, with `dictionary`'s zstd dictionary if given: the bytes
/// decompressed and the frame's length in the payload.
fn decompress_into(
    payload: &[u8],
    out: &mut [u8],
    max: usize,
    dictionary: Option<&Dictionary>,
    whole: bool,
) -> Result<(usize, usize), DecodeError> {
    if payload.len() > max {
        return Err(DecodeError::Malformed(format!(
            "payload of {} bytes exceeds the limit of {max}",
            payload.len()
        )));
    }
    let n = DECODER
        .with(|cell| -> Result<(usize, usize), String> {
            let mut slot = cell.try_borrow_mut().map_err(|e| e.to_string())?;
            let state = match &mut *slot {
                Some(state) => state,
                empty => empty.insert(DecodeState {
                    zstd: zstd::zstd_safe::DCtx::try_create().ok_or("zstd: no decompression context")?,
                    frame: Vec::with_capacity(MAX_PAYLOAD_BYTES_MEDIAN + 4),
                }),
            };
            state.frame.clear();
            state.frame.extend_from_slice(&ZSTD_FRAME_MAGIC);
            state.frame.extend_from_slice(payload);
            // One frame that is the whole payload (or, for codec 7, starts it) and records its
            // content size (`docs/FORMAT.md`): zstd alone would also take frames back to back,
            // or skippable ones.
            let len = zstd::zstd_safe::find_frame_compressed_size(&state.frame).ok();
            let fits = len.is_some_and(|n| {
                if whole {
                    n == state.frame.len()
                } else {
                    n <= state.frame.len()
                }
            });
            if !fits || !matches!(zstd::zstd_safe::get_frame_content_size(&state.frame), Ok(Some(_))) {
                return Err("not one zstd frame with its content size".into());
            }
            let len = len.unwrap_or(0);
            // A file has one dictionary or none, so a frame names none.
            if zstd::zstd_safe::get_dict_id_from_frame(&state.frame).is_some() {
                return Err("a zstd frame that names a dictionary".into());
            }
            let frame = &state.frame[..len];
            let n = match dictionary.and_then(Dictionary::ddict) {
                Some(d) => state.zstd.decompress_using_ddict(&mut *out, frame, d),
                None => state.zstd.decompress(&mut *out, frame),
            }
            .map_err(|code| format!("zstd: {}", zstd::zstd_safe::get_error_name(code)))?;
            Ok((n, len - ZSTD_FRAME_MAGIC.len()))
        })
        .map_err(DecodeError::Malformed)?;
    Ok(n)
}

/// The values of value residuals, checked within `[-(layers+1), layers+1]`.
fn checked_values(residuals: &[u8; BRICK_VOXELS], layers: u8) -> Result<BrickValues, DecodeError> {
    let values = unpredict::<i8>(bytemuck::cast_ref(residuals));
    let limit = i8::try_from(layers as u16 + 1).unwrap_or(i8::MAX);
    // Checked without branches first, since almost every brick passes.
    if values.iter().fold(true, |ok, &v| ok & (-limit..=limit).contains(&v)) {
        return Ok(values);
    }
    let voxel = values.iter().position(|&v| !(-limit..=limit).contains(&v)).unwrap_or(0);
    Err(DecodeError::ValueOutOfRange {
        voxel,
        value: values[voxel],
        limit: limit as i16,
    })
}

/// Decompress one payload of codec 1 and check it holds 512 values within
/// `[-(layers+1), layers+1]`.
///
/// The error says why; the caller knows which brick it was. A decompression context is
/// kept per thread because creating one costs more than decompressing a brick.
pub fn decode_brick(payload: &[u8], layers: u8) -> Result<BrickValues, DecodeError> {
    let mut residuals = [0u8; BRICK_VOXELS];
    decompress(payload, &mut residuals, MAX_PAYLOAD_BYTES)?;
    checked_values(&residuals, layers)
}

/// Decompress one payload of codec 2: the values, checked as [`decode_brick`] does, and the
/// distances, each within ± the reach of `layers` (in steps); those that no contact reads
/// replaced by their [`outer_distance`], as versions 3 and 4 give them.
pub fn decode_brick_with_distances(payload: &[u8], layers: u8) -> Result<(BrickValues, BrickDistances), DecodeError> {
    let mut raw = [0u8; DISTANCE_FRAME_BYTES];
    decompress(payload, &mut raw, MAX_PAYLOAD_BYTES_DISTANCE)?;
    let residuals: &[u8; BRICK_VOXELS] = raw[..BRICK_VOXELS].try_into().expect("512 bytes");
    let values = checked_values(residuals, layers)?;
    let mut r = [0i16; BRICK_VOXELS];
    for (i, r) in r.iter_mut().enumerate() {
        *r = unzigzag(raw[BRICK_VOXELS + i] as u16 | (raw[2 * BRICK_VOXELS + i] as u16) << 8);
    }
    let mut d = unpredict(&r);
    check_distances(&values, &d, layers)?;
    // Version 2 stored them all; a voxmap holds the bounds of those no contact reads.
    bound_outer_distances(&values, &mut d);
    Ok((values, d))
}

/// Decompress a payload of codec 3 or 4, whose frame holds the value residuals and then the
/// distances' (of a length the codec checks), into `raw`: its values, checked as
/// [`decode_brick`] does, and the frame's length.
fn values_of_frame(
    payload: &[u8],
    raw: &mut [u8],
    max: usize,
    layers: u8,
    dictionary: Option<&Dictionary>,
) -> Result<(BrickValues, usize), DecodeError> {
    let (n, _) = decompress_into(payload, raw, max, dictionary, true)?;
    if n < BRICK_VOXELS {
        return Err(DecodeError::Malformed(format!(
            "decompressed to {n} bytes, fewer than the {BRICK_VOXELS} values"
        )));
    }
    let residuals: &[u8; BRICK_VOXELS] = raw[..BRICK_VOXELS].try_into().expect("512 bytes");
    Ok((checked_values(residuals, layers)?, n))
}

/// Decompress one payload of codec 3: the values, checked as [`decode_brick`] does, and the
/// distances, those of the voxels a contact reads from the payload, each within ± the reach of
/// `layers` (in steps), the others their [`outer_distance`].
pub fn decode_brick_with_read_distances(
    payload: &[u8],
    layers: u8,
) -> Result<(BrickValues, BrickDistances), DecodeError> {
    let mut raw = [0u8; DISTANCE_FRAME_BYTES];
    let (values, n) = values_of_frame(payload, &mut raw, MAX_PAYLOAD_BYTES_DISTANCE, layers, None)?;
    // Summed in u16 lanes: `filter().count()` widens every lane to 64 bits.
    let read = values.iter().map(|&v| distance_is_read(v) as u16).sum::<u16>() as usize;
    if n != BRICK_VOXELS + 2 * read {
        return Err(DecodeError::Malformed(format!(
            "decompressed to {n} bytes instead of {} for {read} distances",
            BRICK_VOXELS + 2 * read
        )));
    }
    let (low, high) = raw[BRICK_VOXELS..n].split_at(read);
    // The prediction undone row by row, as `unpredict`, the voxels not stored taking their
    // bound.
    let mut d = [0i16; BRICK_VOXELS];
    let mut next = 0;
    for row in 0..BRICK_VOXELS / 8 {
        let start = row * 8;
        let mut acc = prediction(&d, start);
        for x in start..start + 8 {
            acc = if distance_is_read(values[x]) {
                let r = unzigzag(low[next] as u16 | (high[next] as u16) << 8);
                next += 1;
                acc.wrapping_add(r)
            } else {
                outer_distance(values[x])
            };
            d[x] = acc;
        }
    }
    check_distances(&values, &d, layers)?;
    Ok((values, d))
}

/// Decompress one payload of codec 4: the values, checked as [`decode_brick`] does, and the
/// distances, those of the voxels a contact reads from the residual stream (`median.rs`),
/// each within ± the reach of `layers` (in steps), the others their [`outer_distance`].
pub fn decode_brick_with_median_distances(
    payload: &[u8],
    layers: u8,
) -> Result<(BrickValues, BrickDistances), DecodeError> {
    let mut brick = StoredBrick::EMPTY;
    decode_median_into(payload, layers, None, Predictor::Nine, &mut brick)?;
    Ok((brick.values, brick.distances.unwrap_or([0; BRICK_VOXELS])))
}

/// A payload of codec 4, or of codec 5 or 6 with the file's `dictionary` if it has one, its
/// distances predicted by `predictor`, decoded into `out`, whose distances it sets.
fn decode_median_into(
    payload: &[u8],
    layers: u8,
    dictionary: Option<&Dictionary>,
    predictor: Predictor,
    out: &mut StoredBrick,
) -> Result<(), DecodeError> {
    let mut raw = [0u8; MEDIAN_FRAME_BYTES];
    let (values, n) = values_of_frame(payload, &mut raw, MAX_PAYLOAD_BYTES_MEDIAN, layers, dictionary)?;
    out.values = values;
    let d = out.distances.get_or_insert([0; BRICK_VOXELS]);
    median::decode_into(&out.values, &raw[BRICK_VOXELS..n], predictor, d).map_err(DecodeError::Malformed)?;
    check_distances(&out.values, d, layers)
}

/// A payload of codec 7 decoded into `out`, whose distances it sets: the values frame with the
/// file's zstd dictionary, if it has one, then the distances with its rANS tables.
fn decode_diagonal_into(
    payload: &[u8],
    layers: u8,
    dictionary: Option<&Dictionary>,
    out: &mut StoredBrick,
) -> Result<(), DecodeError> {
    let tables = dictionary
        .and_then(Dictionary::tables)
        .ok_or_else(|| DecodeError::Malformed("a codec 7 payload without the file's rANS tables".into()))?;
    let mut raw = [0u8; BRICK_VOXELS];
    let (n, frame) = decompress_into(payload, &mut raw, MAX_PAYLOAD_BYTES_MEDIAN, dictionary, false)?;
    if n != BRICK_VOXELS {
        return Err(DecodeError::Malformed(format!(
            "the values decompressed to {n} bytes instead of {BRICK_VOXELS}"
        )));
    }
    out.values = checked_values(&raw, layers)?;
    let d = out.distances.get_or_insert([0; BRICK_VOXELS]);
    diagonal::decode_into(&out.values, &payload[frame..], tables, d).map_err(DecodeError::Malformed)?;
    check_distances(&out.values, d, layers)
}

/// The fault [`distance_fault`] finds in `d`, the distances of a brick of `values`, as an
/// error.
fn check_distances(values: &BrickValues, d: &BrickDistances, layers: u8) -> Result<(), DecodeError> {
    distance_fault(values, d, layers).map_or(Ok(()), |fault| Err(DecodeError::Malformed(fault)))
}

/// What is wrong with the first of `d`, the distances of a brick of `values`, that lies beyond
/// ± the reach of `layers` (in steps) or, where a contact reads it, on the other side than its
/// value says ([`distance_on_its_side`]); `None` if none does. The writer and the reader hold
/// distances to the same rules.
pub(super) fn distance_fault(values: &BrickValues, d: &BrickDistances, layers: u8) -> Option<String> {
    let limit = i32::from(far_distance(layers, 1));
    // Checked without branches first, as the values are.
    let bad = |i: usize| (d[i] as i32).abs() > limit || !distance_on_its_side(values[i], d[i]);
    if !(0..BRICK_VOXELS).fold(false, |any, i| any | bad(i)) {
        return None;
    }
    let voxel = (0..BRICK_VOXELS).position(bad).unwrap_or(0);
    let why = if (d[voxel] as i32).abs() > limit {
        format!("beyond the reach of {limit}")
    } else {
        format!("on the wrong side for its value {}", values[voxel])
    };
    Some(format!("voxel {voxel} has distance {} steps, {why}", d[voxel]))
}

/// Decode a payload of `codec`: the values, and the distances for codecs 2 to 7; codecs 5 to 7
/// with the file's `dictionary`, if it has one (the others take none; codec 7 needs its
/// tables).
pub fn decode_payload(
    payload: &[u8],
    layers: u8,
    codec: u8,
    dictionary: Option<&Dictionary>,
) -> Result<(BrickValues, Option<BrickDistances>), DecodeError> {
    let mut brick = StoredBrick::EMPTY;
    decode_payload_into(payload, layers, codec, dictionary, &mut brick)?;
    Ok((brick.values, brick.distances))
}

/// [`decode_payload`] into `out`, where the brick will stay (a cache's brick): codecs 4 to 7
/// decode in place, the older ones are moved in. On an error `out` holds no brick to use.
pub fn decode_payload_into(
    payload: &[u8],
    layers: u8,
    codec: u8,
    dictionary: Option<&Dictionary>,
    out: &mut StoredBrick,
) -> Result<(), DecodeError> {
    match codec {
        CODEC_DIAGONAL_RANS => return decode_diagonal_into(payload, layers, dictionary, out),
        CODEC_ZSTD_MEDIAN_ROWS => return decode_median_into(payload, layers, dictionary, Predictor::Rows, out),
        CODEC_ZSTD_MEDIAN_DICTIONARY => return decode_median_into(payload, layers, dictionary, Predictor::Nine, out),
        CODEC_ZSTD_MEDIAN_DISTANCE => return decode_median_into(payload, layers, None, Predictor::Nine, out),
        CODEC_ZSTD_DELTA_READ_DISTANCE => {
            let (v, d) = decode_brick_with_read_distances(payload, layers)?;
            (out.values, out.distances) = (v, Some(d));
        }
        CODEC_ZSTD_DELTA_DISTANCE => {
            let (v, d) = decode_brick_with_distances(payload, layers)?;
            (out.values, out.distances) = (v, Some(d));
        }
        _ => (out.values, out.distances) = (decode_brick(payload, layers)?, None),
    }
    Ok(())
}

#[cfg(test)]
mod tests;
