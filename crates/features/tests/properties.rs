//! Invariants of the Hamming distance and of the matchers, checked against brute force.

use proptest::prelude::*;
use vofront_features::{
    knn2, match_descriptors, match_windowed, Descriptor, Feature, FeatureError, Features,
    MatchConfig,
};

fn descriptor() -> impl Strategy<Value = Descriptor> {
    any::<[u64; 4]>().prop_map(Descriptor)
}

/// Descriptors near a few centres, so that ties, near-ties and ratio decisions all occur.
fn clustered(n: usize) -> impl Strategy<Value = Vec<Descriptor>> {
    prop::collection::vec((0usize..4, any::<u8>(), any::<u8>()), 0..n).prop_map(|v| {
        let centres = [
            [0u64; 4],
            [u64::MAX; 4],
            [0x5555_5555_5555_5555; 4],
            [0x0f0f_0f0f_0f0f_0f0f; 4],
        ];
        v.into_iter()
            .map(|(c, a, b)| {
                let mut d = centres[c];
                d[(a % 4) as usize] ^= 1 << (a % 64);
                d[(b % 4) as usize] ^= (b as u64) << 3;
                Descriptor(d)
            })
            .collect()
    })
}

/// Reference: nearest (smallest index on ties) and second distance by a plain double loop.
fn brute(q: &Descriptor, train: &[Descriptor]) -> (u32, u32, u32) {
    let mut best = (u32::MAX, u32::MAX);
    let mut second = u32::MAX;
    for (t, d) in train.iter().enumerate() {
        let dist: u32 = q.0.iter().zip(d.0).map(|(a, b)| (a ^ b).count_ones()).sum();
        if dist < best.1 {
            second = best.1;
            best = (t as u32, dist);
        } else if dist < second {
            second = dist;
        }
    }
    (best.0, best.1, second)
}

fn features(pos: &[(f32, f32, u8)], desc: &[Descriptor]) -> Features {
    pos.iter()
        .zip(desc)
        .map(|(&(x, y, level), &descriptor)| Feature {
            x,
            y,
            level,
            scale: 1.2f32.powi(level as i32),
            angle: 0.0,
            response: 1.0,
            descriptor,
        })
        .collect()
}

proptest! {
    #[test]
    fn hamming_is_a_metric(a in descriptor(), b in descriptor(), c in descriptor()) {
        prop_assert_eq!(a.hamming(&a), 0);
        prop_assert_eq!(a.hamming(&b), b.hamming(&a));
        prop_assert!(a.hamming(&c) <= a.hamming(&b) + b.hamming(&c));
        prop_assert!(a.hamming(&b) <= 256);
        prop_assert_eq!(Descriptor::from_bytes(&a.to_bytes()), a);
        let bits = (0..256).filter(|&i| a.bit(i) != b.bit(i)).count() as u32;
        prop_assert_eq!(bits, a.hamming(&b));
    }

    #[test]
    fn knn2_equals_brute_force(q in clustered(40), t in clustered(60)) {
        let k = knn2(&q, &t);
        for (qi, kk) in q.iter().zip(&k) {
            prop_assert_eq!((kk.best, kk.best_distance, kk.second_distance), brute(qi, &t));
        }
    }

    #[test]
    fn match_filters_agree_with_their_definitions(
        q in clustered(40),
        t in clustered(40),
        ratio in prop::option::of(0.5f32..1.0),
        max_distance in 0u32..80,
        cross_check in any::<bool>(),
    ) {
        let cfg = MatchConfig { ratio, cross_check, max_distance };
        let got = match_descriptors(&q, &t, &cfg);
        let mut want = Vec::new();
        for (qi, d) in q.iter().enumerate() {
            let (best, d1, d2) = brute(d, &t);
            if best == u32::MAX || d1 > max_distance {
                continue;
            }
            if let Some(r) = ratio {
                if d2 != u32::MAX && (d1 as f32) >= r * d2 as f32 {
                    continue;
                }
            }
            if cross_check && brute(&t[best as usize], &q).0 != qi as u32 {
                continue;
            }
            want.push((qi as u32, best, d1));
        }
        let got: Vec<_> = got.iter().map(|m| (m.query, m.train, m.distance)).collect();
        prop_assert_eq!(got, want);
    }

    #[test]
    fn windowed_matching_equals_brute_force_over_the_window(
        q in clustered(30),
        t in clustered(30),
        qpos in prop::collection::vec((0f32..200.0, 0f32..150.0, 0u8..4), 30),
        tpos in prop::collection::vec((0f32..200.0, 0f32..150.0, 0u8..4), 30),
        radius in 5f32..60.0,
        tol in prop::option::of(0u8..2),
        cross_check in any::<bool>(),
    ) {
        let (qf, tf) = (features(&qpos[..q.len()], &q), features(&tpos[..t.len()], &t));
        let predicted: Vec<(f32, f32)> = qpos[..q.len()].iter().map(|p| (p.0 + 3.0, p.1 - 2.0)).collect();
        let cfg = MatchConfig { ratio: Some(0.8), cross_check, max_distance: 256 };
        let got = match_windowed(&qf, &predicted, &tf, radius, tol, &cfg).unwrap();
        let in_window = |qi: usize, ti: usize| {
            let (dx, dy) = (tf.xs()[ti] - predicted[qi].0, tf.ys()[ti] - predicted[qi].1);
            dx * dx + dy * dy <= radius * radius
                && tol.is_none_or(|k| tf.levels()[ti].abs_diff(qf.levels()[qi]) <= k)
        };
        let mut want = Vec::new();
        for qi in 0..q.len() {
            let cand: Vec<usize> = (0..t.len()).filter(|&ti| in_window(qi, ti)).collect();
            let sub: Vec<Descriptor> = cand.iter().map(|&ti| t[ti]).collect();
            let (b, d1, d2) = brute(&q[qi], &sub);
            if b == u32::MAX || (d2 != u32::MAX && d1 as f32 >= 0.8 * d2 as f32) {
                continue;
            }
            let ti = cand[b as usize];
            if cross_check {
                // Nearest query (smallest index on ties) among those whose window holds ti.
                let back = (0..q.len())
                    .filter(|&qj| in_window(qj, ti))
                    .min_by_key(|&qj| (q[qj].hamming(&t[ti]), qj));
                if back != Some(qi) {
                    continue;
                }
            }
            want.push((qi as u32, ti as u32, d1));
        }
        let got: Vec<_> = got.iter().map(|m| (m.query, m.train, m.distance)).collect();
        prop_assert_eq!(got, want);
    }
}

#[test]
fn windowed_matching_rejects_bad_arguments() {
    let f = features(&[(1.0, 2.0, 0)], &[Descriptor::default()]);
    let cfg = MatchConfig::default();
    assert!(matches!(
        match_windowed(&f, &[], &f, 5.0, None, &cfg),
        Err(FeatureError::LengthMismatch {
            expected: 1,
            got: 0
        })
    ));
    assert!(matches!(
        match_windowed(&f, &[(1.0, 2.0)], &f, f32::NAN, None, &cfg),
        Err(FeatureError::InvalidRadius(_))
    ));
    let empty = Features::default();
    assert!(match_windowed(&empty, &[], &f, 5.0, None, &cfg)
        .unwrap()
        .is_empty());
    assert!(match_windowed(&f, &[(f32::NAN, 0.0)], &f, 5.0, None, &cfg)
        .unwrap()
        .is_empty());
}
