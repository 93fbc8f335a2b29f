//! The local map's query for tracking: a point's representative and recent descriptors.

use nalgebra::{Isometry3, Point3, Vector2};
use vofront_core::{Camera, Pinhole};
use vofront_features::{Descriptor, Feature, Features, Match};

use super::LocalMap;

/// A feature at `(x, y)` on level 0 with the descriptor `[d, 0, 0, 0]`.
fn feature(x: f32, y: f32, d: u64) -> Feature {
    Feature {
        x,
        y,
        level: 0,
        scale: 1.0,
        angle: 0.0,
        response: 1.0,
        descriptor: Descriptor([d, 0, 0, 0]),
    }
}

fn features(list: &[Feature]) -> Features {
    let mut f = Features::default();
    for x in list {
        f.push(*x);
    }
    f
}

/// A map of two points 10 m ahead of a keyframe at the origin, made from its features 0 and 1
/// (descriptors 1 and 2).
fn two_point_map(camera: &Camera) -> LocalMap {
    let mut map = LocalMap::default();
    let kf = features(&[feature(320.0, 240.0, 1), feature(420.0, 240.0, 2)]);
    let k = map.push_keyframe(Isometry3::identity(), kf, 0);
    for (f, u) in [(0u32, 320.0), (1, 420.0)] {
        let p = camera.pinhole.back_project(&Vector2::new(u, 240.0), 10.0);
        map.add_point(Point3::from(p), &[(k, f)]);
    }
    map
}

/// A point found with another descriptor than its representative one is queried with both,
/// in adjacent entries of the same id and position, and counted visible once; a point found
/// with its own descriptor, or never found since, keeps one entry.
#[test]
fn a_tracked_point_is_queried_with_its_representative_and_its_recent_descriptor() {
    let camera = Camera::pinhole(Pinhole::new(500.0, 500.0, 320.0, 240.0).unwrap());
    let mut map = two_point_map(&camera);
    let (query, _, ids) = map.local_points(&camera, &Isometry3::identity(), (640, 480), 1.2);
    assert_eq!(query.len(), 2);

    // The current frame finds point 0 with descriptor 7 and point 1 with its own (2).
    let current = features(&[feature(321.0, 240.0, 7), feature(421.0, 240.0, 2)]);
    let matches = [
        Match {
            query: 0,
            train: 0,
            distance: 3,
        },
        Match {
            query: 1,
            train: 1,
            distance: 0,
        },
    ];
    let world: Vec<Point3<f64>> = ids.iter().map(|id| map.points[id].position).collect();
    let tracked = map.keep_inliers(&current, &matches, &world, &[true, true], &ids);
    assert_eq!(tracked.len(), 2);

    let visible_before: Vec<u32> = ids.iter().map(|id| map.points[id].visible).collect();
    let (query, positions, again) =
        map.local_points(&camera, &Isometry3::identity(), (640, 480), 1.2);
    let descriptors: Vec<u64> = query.descriptors().iter().map(|d| d.0[0]).collect();
    assert_eq!(descriptors, [1, 7, 2]);
    assert_eq!(again, [ids[0], ids[0], ids[1]]);
    assert_eq!(positions[0], positions[1]);
    assert_eq!(
        (query.xs()[0], query.ys()[0]),
        (query.xs()[1], query.ys()[1])
    );
    for (id, before) in ids.iter().zip(visible_before) {
        assert_eq!(map.points[id].visible, before + 1);
        assert_eq!(map.points[id].found, 2);
    }
}

/// A point out of the image is queried once, whatever it was found with.
#[test]
fn a_point_out_of_view_has_one_entry() {
    let camera = Camera::pinhole(Pinhole::new(500.0, 500.0, 320.0, 240.0).unwrap());
    let mut map = two_point_map(&camera);
    for p in map.points.values_mut() {
        p.recent = Some(Descriptor([9, 0, 0, 0]));
    }
    let behind = Isometry3::translation(0.0, 0.0, -20.0);
    let (query, _, ids) = map.local_points(&camera, &behind, (640, 480), 1.2);
    assert_eq!(query.len(), 2);
    assert!(query.xs().iter().all(|x| x.is_nan()));
    assert_ne!(ids[0], ids[1]);
}
