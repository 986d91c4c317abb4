use sc_vector::*;
use std::f64::consts::*;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let f = read::read_file(std::path::Path::new(&a[1])).unwrap();
    let edges = match a[2].as_str() { "gc" => Edges::GreatCircle, "rh" => Edges::Rhumb, _ => Edges::Lonlat };
    let style = Style { fill: Rgba([200, 120, 40, 160]), stroke: Rgba([255,255,255,255]), width: 1.0, ..Style::default() };
    let l = VectorLayer::new(f, style, edges, 6_371_000.0).unwrap();
    let w: usize = a[3].parse().unwrap();
    let win = Window { lon0: -PI, colat0: 0.0, dlon: TAU / w as f64, dcolat: PI / (w/2) as f64, w, h: w/2 };
    let t = std::time::Instant::now();
    let px = l.render(&win, 1.0);
    eprintln!("{:?} segs {}", t.elapsed(), l.segment_count());
    let mut img = image::RgbaImage::new(w as u32, (w/2) as u32);
    for (i, p) in img.pixels_mut().enumerate() { let q = &px[i*4..i*4+4]; let a = q[3] as f32/255.0; *p = image::Rgba([(q[0] as f32*a) as u8,(q[1] as f32*a) as u8,(q[2] as f32*a) as u8,255]); }
    img.save(&a[4]).unwrap();
}
