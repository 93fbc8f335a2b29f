//! The registry's names, aliases, needs and alignments.

use nalgebra::Isometry3;

use super::*;

#[test]
fn names_and_aliases_parse_to_their_kind() {
    for (name, kind) in [
        ("direct", TrackerKind::Direct),
        ("feature-rgbd", TrackerKind::FeatureRgbd),
        ("feature_rgbd", TrackerKind::FeatureRgbd),
        ("mono", TrackerKind::Mono),
        ("feature", TrackerKind::Mono),
        ("stereo", TrackerKind::Stereo),
        ("direct-stereo", TrackerKind::DirectStereo),
        ("direct_stereo", TrackerKind::DirectStereo),
        ("direct-mono", TrackerKind::DirectMono),
        ("direct_mono", TrackerKind::DirectMono),
    ] {
        assert_eq!(name.parse::<TrackerKind>().unwrap(), kind, "{name}");
    }
    for kind in TrackerKind::ALL {
        assert_eq!(kind.name().parse::<TrackerKind>().unwrap(), *kind);
        assert_eq!(kind.to_string(), kind.name());
    }
    let err = "sideways".parse::<TrackerKind>().unwrap_err().to_string();
    assert_eq!(
        err,
        "unknown tracker method 'sideways' (known: direct, feature-rgbd, mono, stereo, \
         direct-stereo, direct-mono; aliases feature_rgbd, feature, direct_stereo, direct_mono)"
    );
}

#[test]
fn only_the_mono_kinds_are_similarity_aligned_and_only_the_stereo_kinds_need_a_right_image() {
    let needs: Vec<_> = TrackerKind::ALL
        .iter()
        .map(|k| (k.needs_depth(), k.needs_right()))
        .collect();
    assert_eq!(
        needs,
        [
            (true, false),
            (true, false),
            (false, false),
            (false, true),
            (false, true),
            (false, false)
        ]
    );
    for kind in TrackerKind::ALL {
        let want = if matches!(kind, TrackerKind::Mono | TrackerKind::DirectMono) {
            Alignment::Sim3
        } else {
            Alignment::Se3
        };
        assert_eq!(kind.alignment(), want, "{kind}");
    }
}

#[test]
fn every_kind_builds_for_its_rig_and_any_budget() {
    let camera = default_camera();
    let right_in_left = Isometry3::translation(0.1, 0.0, 0.0);
    let mono = Rig::mono(camera).unwrap();
    let stereo = Rig::stereo(camera, Isometry3::identity(), camera, right_in_left).unwrap();
    for kind in TrackerKind::ALL {
        for features in [None, Some(300)] {
            let options = TrackerOptions { features };
            let built = kind.build_for_rig(&stereo, &options);
            assert!(built.is_ok(), "{kind} {features:?}");
            assert_eq!(built.unwrap().needs_right(), kind.needs_right(), "{kind}");
            let on_mono = kind.build_for_rig(&mono, &options);
            let by_camera = kind.build(camera, &options);
            if kind.needs_right() {
                for err in [on_mono.err(), by_camera.err()] {
                    assert!(
                        matches!(err, Some(OdometryError::NeedsStereoRig { .. })),
                        "{kind}"
                    );
                }
            } else {
                assert!(on_mono.is_ok() && by_camera.is_ok(), "{kind}");
            }
        }
    }
}

#[test]
fn the_direct_kinds_align_pixels_and_the_others_match_features() {
    for kind in TrackerKind::ALL {
        let direct = kind.name().starts_with("direct");
        let want = if direct {
            Paradigm::Direct
        } else {
            Paradigm::Feature
        };
        assert_eq!(kind.paradigm(), want, "{kind}");
    }
    assert_eq!(Paradigm::Direct.residual_unit(), "grey levels");
    assert_eq!(Paradigm::Feature.residual_unit(), "px");
}

#[test]
fn the_default_camera_is_the_tum_ros_preset() {
    let preset = crate::presets::camera_preset("tum-ros").map(|p| p.camera);
    assert_eq!(Some(default_camera()), preset);
}
