//! The cargo features that select the configurations a build holds
//! (`m1-pa` … `m4-ps`, default `all-configs`): with the default features
//! every configuration is built and dispatched to its own types.

use rollcal::models::ConfigId;

#[test]
fn default_features_build_all_seven() {
    for id in ConfigId::ALL {
        assert!(id.is_built(), "{id} not built with the default features");
    }
    assert_eq!(ConfigId::first_built(), ConfigId::M1Pa);
}

#[test]
fn with_built_config_dispatches_like_with_config() {
    for id in ConfigId::ALL {
        let built = rollcal::with_built_config!(id, |M, N, Z| Some((N, Z)), else |_other| None);
        let all = rollcal::with_config!(id, |M, N, Z| (N, Z));
        let layout = id.layout();
        assert_eq!(built, Some(all), "{id}");
        assert_eq!(all, (layout.n(), layout.z()), "{id}");
    }
}
