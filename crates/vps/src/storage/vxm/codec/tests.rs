//! The codecs against their definitions in `docs/FORMAT.md`, and junk refused.

use super::*;
use crate::voxmap::DISTANCE_STEP;

#[test]
fn predictor_round_trips() {
    let mut v = [0i8; BRICK_VOXELS];
    for (i, x) in v.iter_mut().enumerate() {
        *x = ((i * 37 % 255) as i32 - 127) as i8;
    }
    assert_eq!(unpredict::<i8>(bytemuck::cast_ref(&predict(&v))), v);
}

#[test]
fn codec_round_trips_and_rejects_junk() {
    let mut c = new_compressor().unwrap();
    let mut v = [-3i8; BRICK_VOXELS];
    v[100] = 0;
    v[511] = 3;
    let p = encode_brick(&mut c, &v).unwrap();
    assert!(p.len() < 64, "{}", p.len());
    assert_eq!(decode_brick(&p, 2).unwrap(), v);
    assert!(decode_brick(&p, 1).is_err());
    assert!(decode_brick(&[], 2).is_err());
    assert!(decode_brick(&p[..p.len() - 1], 2).is_err());
    assert!(decode_brick(&[0u8; 2000], 2).is_err());
}

#[test]
fn the_bound_of_a_layer_is_half_a_voxel_inside_it() {
    for v in i8::MIN..=-2 {
        assert_eq!(outer_distance(v) as f64 * DISTANCE_STEP, v as f64 + 0.5, "value {v}");
    }
}

#[test]
fn the_side_rule_reads_as_documented() {
    for v in -8i8..=8 {
        for d in -300i16..=300 {
            // `docs/FORMAT.md`: positive for values ≥ 1, negative for −1, anything for 0
            // and for the values whose distances no contact reads.
            let documented = v <= -2 || v == 0 || (v >= 1 && d > 0) || (v == -1 && d < 0);
            assert_eq!(distance_on_its_side(v, d), documented, "value {v}, distance {d}");
        }
    }
}

#[test]
fn zigzag_round_trips_every_residual() {
    for r in i16::MIN..=i16::MAX {
        assert_eq!(unzigzag(zigzag(r)), r);
    }
    assert_eq!([0, -1, 1, -2].map(zigzag), [0, 1, 2, 3]);
}

#[test]
fn distance_codec_round_trips_and_rejects_junk() {
    let mut c = new_compressor().unwrap();
    let mut v = [-3i8; BRICK_VOXELS];
    v[100] = 0;
    // A plane's distances in voxels, rounded to the step, clamped at -3.5 (the reach of 3
    // layers); one voxel 2.7 voxels away, within the reach of 3 layers, not of 2 (2.5).
    let steps = |voxels: f64| (voxels / DISTANCE_STEP).round() as i16;
    let mut d = [0i16; BRICK_VOXELS];
    for (i, x) in d.iter_mut().enumerate() {
        let along = 0.37 * (i & 7) as f64 + 0.21 * ((i >> 3) & 7) as f64 - 0.13 * (i >> 6) as f64;
        *x = steps((along - 2.0).max(-3.5));
    }
    d[5] = steps(2.7);
    v[5] = 3;
    let p = encode_brick_with_distances(&mut c, &v, &d).unwrap();
    assert!(p.len() < 300, "{}", p.len());
    // Read back with the bounds of the voxels no contact reads, as a voxmap holds them.
    let mut bounded = d;
    bound_outer_distances(&v, &mut bounded);
    assert_ne!(bounded, d);
    assert_eq!((bounded[5], bounded[100], bounded[0]), (d[5], d[100], steps(-2.5)));
    assert_eq!(decode_brick_with_distances(&p, 3).unwrap(), (v, bounded));
    assert_eq!(
        decode_payload(&p, 3, CODEC_ZSTD_DELTA_DISTANCE, None).unwrap(),
        (v, Some(bounded))
    );
    // With 2 layers the values of -3 are in range, the distance of 2.7 voxels is not.
    assert!(matches!(decode_brick_with_distances(&p, 2), Err(DecodeError::Malformed(m)) if m.contains("distance")));
    assert!(matches!(
        decode_brick_with_distances(&p, 1),
        Err(DecodeError::ValueOutOfRange { .. })
    ));
    assert!(decode_brick(&p, 3).is_err());
    assert!(decode_brick_with_distances(&p[..p.len() - 1], 3).is_err());
    assert!(decode_brick_with_distances(&[0u8; 3000], 3).is_err());
}

/// Codecs 3 and 4 store the distances of the voxels at −1 and above only, decode the others to
/// their bounds, and refuse a frame whose length does not match its values.
#[test]
fn read_distance_codecs_round_trip_and_reject_junk() {
    read_distance_codec_round_trips_and_rejects_junk(
        encode_brick_with_read_distances,
        decode_brick_with_read_distances,
        CODEC_ZSTD_DELTA_READ_DISTANCE,
        2,
    );
    read_distance_codec_round_trips_and_rejects_junk(
        encode_brick_with_median_distances,
        decode_brick_with_median_distances,
        CODEC_ZSTD_MEDIAN_DISTANCE,
        1,
    );
}

type Encoder = fn(&mut zstd::bulk::Compressor<'_>, &BrickValues, &BrickDistances) -> std::io::Result<Vec<u8>>;
type Decoder = fn(&[u8], u8) -> Result<(BrickValues, BrickDistances), DecodeError>;

/// Codec `codec` (3 or 4), whose residuals take at least `residual_bytes` each: the distances
/// of the voxels a contact reads round-trip, the others read as their bound, and bad frames
/// are refused.
fn read_distance_codec_round_trips_and_rejects_junk(
    encode: Encoder,
    decode: Decoder,
    codec: u8,
    residual_bytes: usize,
) {
    let mut c = new_compressor().unwrap();
    let mut rng = crate::shapes::SplitMix(5);
    for round in 0..200 {
        // Random values of 3 layers (mostly far outside in the first rounds) and random
        // distances within the reach, on their values' sides (any for the others).
        let mut v = [0i8; BRICK_VOXELS];
        let mut d = [0i16; BRICK_VOXELS];
        for (v, d) in v.iter_mut().zip(d.iter_mut()) {
            *v = if rng.below(200) < round {
                rng.below(9) as i8 - 4
            } else {
                -4
            };
            let magnitude = rng.below(112) as i16 + 1;
            *d = match *v {
                -1 => -magnitude,
                1.. => magnitude,
                _ => rng.below(225) as i16 - 112,
            };
        }
        let p = encode(&mut c, &v, &d).unwrap();
        let mut want = d;
        bound_outer_distances(&v, &mut want);
        assert_eq!(decode(&p, 3).unwrap(), (v, want));
        assert_eq!(decode_payload(&p, 3, codec, None).unwrap(), (v, Some(want)));
        // The distances of 3 layers reach 3.5 voxels (112 steps), not those of 2.
        if d.iter().zip(&v).any(|(&d, &v)| distance_is_read(v) && d.abs() > 80) {
            assert!(decode(&p, 2).is_err());
        }
        // A distance a contact reads on the wrong side of the surface is refused.
        if let Some(i) = (0..BRICK_VOXELS).find(|&i| v[i] == 1 || v[i] == -1) {
            let mut wrong = d;
            wrong[i] = -wrong[i];
            let p = encode(&mut c, &v, &wrong).unwrap();
            let e = decode(&p, 3).unwrap_err();
            assert!(
                matches!(&e, DecodeError::Malformed(m) if m.contains("wrong side")),
                "{e}"
            );
        }
    }
    // All far outside: nothing but the values is stored.
    let v = [-4i8; BRICK_VOXELS];
    let p = encode(&mut c, &v, &[7; BRICK_VOXELS]).unwrap();
    assert!(p.len() < 32, "{}", p.len());
    let (_, d) = decode(&p, 3).unwrap();
    assert!(d.iter().all(|&d| d == -112), "{d:?}");
    // A frame of other than 512 bytes and a residual for each voxel at −1 and above.
    let mut one_more = predict(&v).to_vec();
    one_more.extend(vec![0; residual_bytes]);
    for raw in [&one_more[..], &one_more[..BRICK_VOXELS - 1]] {
        let p = payload_of(&mut c, raw, MAX_PAYLOAD_BYTES_DISTANCE).unwrap();
        assert!(matches!(decode(&p, 3), Err(DecodeError::Malformed(_))));
    }
    assert!(decode(&[0u8; 3000], 3).is_err());
    assert!(decode(&[], 3).is_err());
    // Exactly one frame, with its content size: not one followed by another, nor one
    // without its size.
    let p = payload_of(&mut c, &predict(&v), MAX_PAYLOAD_BYTES_DISTANCE).unwrap();
    assert!(decode(&p, 3).is_ok());
    let mut two = p.clone();
    two.extend_from_slice(&ZSTD_FRAME_MAGIC);
    two.extend_from_slice(&p);
    let mut without_size = zstd::bulk::Compressor::new(1).unwrap();
    without_size.include_contentsize(false).unwrap();
    let no_size = payload_of(&mut without_size, &predict(&v), MAX_PAYLOAD_BYTES_DISTANCE).unwrap();
    for p in [two, no_size] {
        let e = decode(&p, 3).unwrap_err();
        assert!(
            matches!(&e, DecodeError::Malformed(m) if m.contains("one zstd frame")),
            "{e}"
        );
    }
}
