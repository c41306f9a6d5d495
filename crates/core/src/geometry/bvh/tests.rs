use super::*;
use crate::geometry::Rng;
use glam::Vec2;

/// Every triangle tested, in the BVH's normalised coordinates (the same `f32` arithmetic).
fn brute_closest(bvh: &Bvh, tris: &[TriangleInput], ray: &Ray) -> Option<(f64, u32)> {
    let mut best: Option<(f64, u32)> = None;
    for (k, t) in tris.iter().enumerate() {
        let v0 = bvh.local_point(t.vertices[0]);
        let tri = Tri {
            v0,
            e1: bvh.local_point(t.vertices[1]) - v0,
            e2: bvh.local_point(t.vertices[2]) - v0,
            id: k as u32,
            cull_back: t.cull_back,
            cut: NO_CUT,
        };
        let limit = best.map_or(f32::INFINITY, |b| b.0 as f32);
        let (o, d) = (bvh.local_point(ray.origin), bvh.local_dir(ray.dir));
        if let Some((tt, ..)) = intersect(&tri, tri.cull_back, o, d, 0.0, limit) {
            best = Some((tt as f64, t.id));
        }
    }
    best
}

/// `n` random triangles of unit size in a 10-unit cube (seeded), with ids and culling
/// flags chosen per index.
fn soup(
    seed: u64,
    n: u32,
    id: impl Fn(u32) -> u32,
    cull_back: impl Fn(u32) -> bool,
) -> Vec<TriangleInput> {
    let mut rng = Rng::new(seed, 0);
    let mut r = || rng.next_f64();
    (0..n)
        .map(|i| {
            let c = DVec3::new(r(), r(), r()) * 10.0;
            let mut v = || c + DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
            TriangleInput {
                vertices: [v(), v(), v()],
                id: id(i),
                cull_back: cull_back(i),
                cut: None,
            }
        })
        .collect()
}

#[test]
fn bvh_matches_brute_force() {
    let tris = soup(3, 500, |i| i, |_| false);
    let bvh = Bvh::build(&tris);
    let mut rng = Rng::new(4, 0);
    let mut hits = 0;
    for _ in 0..2000 {
        let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 12.0 - 1.0;
        let d = DVec3::new(
            rng.next_f64() - 0.5,
            rng.next_f64() - 0.5,
            rng.next_f64() - 0.5,
        );
        let ray = Ray::new(o, d);
        let a = bvh.closest_hit(&ray, 0.0, f64::INFINITY);
        let b = brute_closest(&bvh, &tris, &ray);
        assert_eq!(a.map(|h| h.id), b.map(|h| h.1));
        assert_eq!(bvh.any_hit(&ray, 0.0, f64::INFINITY), b.is_some());
        hits += a.is_some() as usize;
    }
    assert!(hits > 200, "test rays should hit something: {hits}");
}

/// Issue 11: the same triangles in another unit (coordinates multiplied by 1e-3 or 1e4,
/// as an OBJ export in millimetres or kilometres would have them) must give the same
/// stored triangles (relative to the scale) and the same hits, with rays aimed exactly
/// at vertices and edges, where an f32 rounding decides. Before the BVH worked in
/// normalised coordinates, `0.45` and `0.00045` rounded differently in f32 (stored
/// triangles 1e-8 apart relative) and f32 barycentrics differed by ~1e-7.
#[test]
fn the_same_scene_in_another_unit_gives_the_same_answers() {
    let mut rng = Rng::new(11, 0);
    let mut r = || (rng.next_f64() * 1000.0).round() / 1000.0; // decimal, as in an OBJ
    let base: Vec<[DVec3; 3]> = (0..200)
        .map(|_| {
            let c = DVec3::new(r(), r(), r()) * 4.0;
            let mut v = || c + DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
            [v(), v(), v()]
        })
        .collect();
    let build = |scale: f64| {
        let input: Vec<TriangleInput> = base
            .iter()
            .enumerate()
            .map(|(i, t)| TriangleInput {
                // Multiplied and written in decimal, then read back.
                vertices: t.map(|v| {
                    let s = format!("{} {} {}", v.x * scale, v.y * scale, v.z * scale);
                    let c: Vec<f64> = s.split(' ').map(|x| x.parse().unwrap()).collect();
                    DVec3::new(c[0], c[1], c[2])
                }),
                id: i as u32,
                cull_back: false,
                cut: None,
            })
            .collect();
        Bvh::build(&input)
    };
    let one = build(1.0);
    for scale in [1e-3, 1e4] {
        let other = build(scale);
        for k in 0..one.triangle_count() as u32 {
            let (a, b) = (one.stored_triangle(k), other.stored_triangle(k));
            for (p, q) in a.iter().zip(&b) {
                assert!(
                    (*p - *q / scale).length() <= 1e-12 * p.length().max(1.0),
                    "scale {scale}, triangle {k}: {p} vs {}",
                    *q / scale
                );
            }
        }
        let mut rng = Rng::new(12, 0);
        for n in 0..3000 {
            let t = &base[n % base.len()];
            // Aimed at a vertex, an edge point or the centroid.
            let w = match n % 3 {
                0 => t[n % 3],
                1 => (t[0] + t[1]) * 0.5,
                _ => (t[0] + t[1] + t[2]) / 3.0,
            };
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 6.0 - 1.0;
            let (ray1, ray2) = (Ray::new(o, w - o), Ray::new(o * scale, (w - o) * scale));
            assert_eq!(
                one.any_hit(&ray1, 1e-9, 1.0 + 1e-9),
                other.any_hit(&ray2, 1e-9, 1.0 + 1e-9),
                "scale {scale}, ray {n}"
            );
            let (h1, h2) = (
                one.closest_hit(&ray1, 0.0, f64::INFINITY),
                other.closest_hit(&ray2, 0.0, f64::INFINITY),
            );
            assert_eq!(h1.map(|h| h.id), h2.map(|h| h.id), "scale {scale}, ray {n}");
            if let (Some(a), Some(b)) = (h1, h2) {
                for (x, y) in [(a.t, b.t), (a.u, b.u), (a.v, b.v)] {
                    assert!(
                        (x - y).abs() <= 1e-9,
                        "scale {scale}, ray {n}: {a:?} vs {b:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn culling_and_front_flag() {
    let tri = TriangleInput {
        vertices: [DVec3::ZERO, DVec3::X, DVec3::Y],
        id: 9,
        cull_back: true,
        cut: None,
    };
    let bvh = Bvh::build(&[tri]);
    let down = Ray::new(DVec3::new(0.2, 0.2, 1.0), DVec3::NEG_Z);
    let up = Ray::new(DVec3::new(0.2, 0.2, -1.0), DVec3::Z);
    let h = bvh.closest_hit(&down, 0.0, 10.0).expect("front hit");
    assert!(h.front && (h.t - 1.0).abs() < 1e-6 && h.id == 9);
    assert!(bvh.closest_hit(&up, 0.0, 10.0).is_none());
    assert!(
        bvh.any_hit(&up, 0.0, 10.0),
        "back faces still block shadow rays"
    );
    assert!(!bvh.any_hit(&down, 0.0, 0.5));
}

/// Subtrees built on another thread are spliced in where a serial build writes them, so
/// the tree (nodes and triangle order) does not depend on the thread split.
#[test]
fn parallel_build_writes_the_serial_tree() {
    let mut rng = Rng::new(5, 0);
    let n = 5000;
    let centers: Vec<DVec3> = (0..n)
        .map(|_| DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 10.0)
        .collect();
    let boxes: Vec<Aabb> = centers
        .iter()
        .map(|&c| {
            let h = DVec3::splat(0.05 + 0.1 * rng.next_f64());
            Aabb {
                min: c - h,
                max: c + h,
            }
        })
        .collect();
    let tree = |parallel_min| {
        let mut idx: Vec<u32> = (0..n as u32).collect();
        let nodes = build::build_tree(&mut idx, &boxes, &centers, parallel_min);
        let flat: Vec<_> = nodes
            .iter()
            .map(|n| (n.min, n.max, n.first_or_right, n.count))
            .collect();
        (flat, idx)
    };
    let serial = tree(usize::MAX);
    let parallel = tree(64);
    assert!(
        serial.0.len() > n / 4,
        "a real tree: {} nodes",
        serial.0.len()
    );
    assert_eq!(serial.0, parallel.0);
    assert_eq!(serial.1, parallel.1);
}

/// A packet answers each ray as [`Bvh::any_hit_except`] answers it alone, whether its rays
/// run together (a link's) or apart, with ids ignored per ray, in packets of 1 to 4.
#[test]
fn packet_answers_each_ray_as_alone() {
    let mut tris = soup(5, 800, |i| i % 97, |i| i % 3 == 0);
    // Every fifth triangle a cut-out (a checkerboard of holes) that rays may pass.
    for t in tris.iter_mut().step_by(5) {
        t.cut = Some(CutOut {
            mask: 0,
            uv: [Vec2::ZERO, Vec2::new(3.0, 0.0), Vec2::new(0.0, 3.0)],
        });
    }
    let masks: Arc<[AlphaMask]> = Arc::new([AlphaMask::new(4, 4, |x, y| (x + y) % 2 == 0)]);
    let bvh = Bvh::build_with_masks(&tris, masks);
    let mut rng = Rng::new(6, 0);
    let mut point = |scale: f64, c: DVec3| {
        c + DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * scale
    };
    let (mut blocked, mut rays_traced) = (0, 0);
    for p in 0..3000 {
        let n = 1 + p % PACKET;
        // Every other packet coherent: ends within a unit of two centres.
        let coherent = p % 2 == 0;
        let (a, b) = (point(10.0, DVec3::ZERO), point(10.0, DVec3::ZERO));
        let packet: Vec<ShadowRay> = (0..n)
            .map(|k| {
                let (o, t) = if coherent {
                    (point(1.0, a), point(1.0, b))
                } else {
                    (
                        point(12.0, DVec3::splat(-1.0)),
                        point(12.0, DVec3::splat(-1.0)),
                    )
                };
                ShadowRay {
                    ray: Ray::new(o, t - o),
                    ignore: [(p * 7 + k) as u32 % 97, (p * 13 + k) as u32 % 97],
                }
            })
            .collect();
        let got = bvh.any_hit_packet(&packet, 1e-9, 1.0 - 1e-9);
        for (k, s) in packet.iter().enumerate() {
            let alone = bvh.any_hit_except(&s.ray, 1e-9, 1.0 - 1e-9, s.ignore);
            assert_eq!(got & (1 << k) != 0, alone, "packet {p}, ray {k} of {n}");
            blocked += alone as usize;
            rays_traced += 1;
        }
    }
    // Both answers occur often enough for the comparison to mean something.
    assert!(
        blocked > rays_traced / 10 && blocked < rays_traced * 9 / 10,
        "{blocked} of {rays_traced}"
    );
}
