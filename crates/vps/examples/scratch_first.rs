use vps::haptics::{contact, CachedVoxmap, ContactParams, Penetration};
use vps::{PointshellFile, Pose};
fn flt() -> i64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap();
    let r = &s[s.rfind(')').unwrap() + 2..];
    r.split(' ').nth(7).unwrap().parse().unwrap()
}
fn main() {
    let a: Vec<String> = std::env::args().collect();
    if std::env::var("PREFAULT").is_ok() {
        let warm = || {
            let mut v: Vec<Box<[u8; 1600]>> = (0..400).map(|_| Box::new([1u8; 1600])).collect();
            let mut a: Vec<[i16; 1000]> = Vec::with_capacity(512);
            for _ in 0..200 {
                a.push([1; 1000]);
            }
            std::hint::black_box(&mut v);
            std::hint::black_box(&mut a);
        };
        rayon::broadcast(|_| warm());
        warm();
    } else {
        rayon::spawn_broadcast(|_| {});
    }
    let pen = match a[3].as_str() {
        "layers" => Penetration::Layers,
        "sharp" => Penetration::Sharp,
        _ => Penetration::Distance,
    };
    let t = std::time::Instant::now();
    let v = CachedVoxmap::open(&a[1]).unwrap();
    let s = PointshellFile::open(&a[2]).unwrap();
    let open = t.elapsed().as_secs_f64() * 1e6;
    let pose = Pose::parse("1240 0 0 1 0 0 0").unwrap();
    let p = ContactParams {
        penetration: pen,
        ..Default::default()
    };
    let f0 = flt();
    let c1 = contact(&v, &s, &pose, &p).unwrap();
    let f1 = flt();
    let st = v.stats();
    v.clear();
    let f2 = flt();
    let c2 = contact(&v, &s, &pose, &p).unwrap();
    let f3 = flt();
    let c3 = contact(&v, &s, &pose, &p).unwrap();
    println!(
        "faults {} {} open {open:.0} first {:.0} cold-cache {:.0} warm {:.0} misses {} tested {}",
        f1 - f0,
        f3 - f2,
        c1.micros,
        c2.micros,
        c3.micros,
        st.misses,
        c1.points_tested
    );
}
