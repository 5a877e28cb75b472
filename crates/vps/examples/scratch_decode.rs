use vps::VoxmapFile;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let f = VoxmapFile::open(&a[1]).unwrap();
    let bytes = std::fs::read(&a[1]).unwrap();
    let idx: Vec<_> = f.index().unwrap().iter().take(20000).copied().collect();
    let mut d = zstd::bulk::Decompressor::new().unwrap();
    let mut frame = Vec::new();
    let mut out = vec![0u8; 1536];
    for round in 0..3 {
        let t = std::time::Instant::now();
        let mut tot = 0usize;
        for e in &idx {
            let p = &bytes[e.offset as usize..e.offset as usize + e.len as usize];
            frame.clear();
            frame.extend_from_slice(&[0x28, 0xb5, 0x2f, 0xfd]);
            frame.extend_from_slice(p);
            tot += d.decompress_to_buffer(&frame[..], &mut out[..]).unwrap();
        }
        let z = t.elapsed().as_secs_f64() * 1e6 / idx.len() as f64;
        let t = std::time::Instant::now();
        for e in &idx {
            std::hint::black_box(f.stored_brick(e.key).unwrap());
        }
        let full = t.elapsed().as_secs_f64() * 1e6 / idx.len() as f64;
        let t = std::time::Instant::now();
        for e in &idx {
            let p = &bytes[e.offset as usize..e.offset as usize + e.len as usize];
            std::hint::black_box(crc32fast::hash(p));
        }
        let crc = t.elapsed().as_secs_f64() * 1e6 / idx.len() as f64;
        println!("round {round}: zstd {z:.3} us, full stored_brick {full:.3} us, crc {crc:.3}, mean raw {:.0} B, mean payload {:.0}", tot as f64 / idx.len() as f64, idx.iter().map(|e| e.len as f64).sum::<f64>() / idx.len() as f64);
    }
}
