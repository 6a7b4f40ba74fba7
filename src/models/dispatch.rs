//! The one `ConfigId` → configuration-type dispatch: [`with_config!`]
//! (every configuration) and [`with_built_config!`] (those built into this
//! crate by its cargo features `m1-pa` … `m4-ps`), their error-model forms
//! [`with_model!`] and [`with_built_model!`] (`ConfigId` and
//! [`ErrorModel`](crate::models::ErrorModel) → `M2Ps` or `M2PsFull`, …), with the hidden helper
//! macros that pass or drop one configuration's arm by this crate's
//! features. All are `#[macro_export]`: their paths are the crate root's
//! (`rollcal::with_config!`).
//!
//! [`with_config!`]: crate::with_config
//! [`with_built_config!`]: crate::with_built_config
//! [`with_model!`]: crate::with_model
//! [`with_built_model!`]: crate::with_built_model

/// The one `ConfigId` → configuration-type dispatch: evaluates `body` with
/// `M` the configuration's model type and `N`, `Z` its state and measurement
/// dimensions as `const`s, for the configuration `id` names.
///
/// ```
/// use rollcal::models::{ConfigId, Model};
/// fn states<M: Model<N, Z>, const N: usize, const Z: usize>() -> usize {
///     N
/// }
/// let n = rollcal::with_config!(ConfigId::M2Ps, |M, N, Z| states::<M, N, Z>());
/// assert_eq!(n, 18);
/// ```
#[macro_export]
macro_rules! with_config {
    ($id:expr, |$m:ident, $n:ident, $z:ident| $body:expr) => {
        match $id {
            $crate::models::ConfigId::M1Pa => $crate::with_config!(@arm M1Pa, 12, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M1Ps => $crate::with_config!(@arm M1Ps, 15, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M2Ps => $crate::with_config!(@arm M2Ps, 18, 6, $m, $n, $z, $body),
            $crate::models::ConfigId::M3Pa => $crate::with_config!(@arm M3Pa, 15, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M3Ps => $crate::with_config!(@arm M3Ps, 18, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M4Pa => $crate::with_config!(@arm M4Pa, 12, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M4Ps => $crate::with_config!(@arm M4Ps, 15, 3, $m, $n, $z, $body),
        }
    };
    (@arm $ty:ident, $nv:literal, $zv:literal, $m:ident, $n:ident, $z:ident, $body:expr) => {{
        #[allow(non_camel_case_types, dead_code)]
        type $m = $crate::models::$ty;
        #[allow(non_upper_case_globals, dead_code)]
        const $n: usize = $nv;
        #[allow(non_upper_case_globals, dead_code)]
        const $z: usize = $zv;
        $body
    }};
}

// One helper macro per configuration, defined by the cargo feature of *this*
// crate (`#[cfg]` inside an exported macro would test the caller's
// features): it passes its tokens through when the configuration is built,
// and drops them otherwise.
#[cfg(feature = "m1-pa")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_pa {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m1-pa"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_pa {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m1-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m1-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_ps {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m2-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m2_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m2-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m2_ps {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m3-pa")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_pa {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m3-pa"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_pa {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m3-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m3-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_ps {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m4-pa")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_pa {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m4-pa"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_pa {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m4-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m4-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_ps {
    ($($t:tt)*) => {};
}

// Likewise one helper per error model of the session's dispatch (cargo
// features `installation-model`, `full-model`).
#[cfg(feature = "installation-model")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_installation_model {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "installation-model"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_installation_model {
    ($($t:tt)*) => {};
}
#[cfg(feature = "full-model")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_full_model {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "full-model"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_full_model {
    ($($t:tt)*) => {};
}

#[cfg(not(any(
    feature = "m1-pa",
    feature = "m1-ps",
    feature = "m2-ps",
    feature = "m3-pa",
    feature = "m3-ps",
    feature = "m4-pa",
    feature = "m4-ps"
)))]
compile_error!("rollcal: enable at least one configuration feature (m1-pa, m1-ps, m2-ps, m3-pa, m3-ps, m4-pa, m4-ps; the default `all-configs` enables the seven)");

#[cfg(not(any(feature = "installation-model", feature = "full-model")))]
compile_error!("rollcal: enable at least one error model in the session's dispatch (installation-model, full-model; the default features enable both)");

/// [`with_config!`] over the configurations built into this crate (cargo
/// features `m1-pa` … `m4-ps`; the default `all-configs` has the seven):
/// only their arms are instantiated, and `fallback` is evaluated, with
/// `other` the [`ConfigId`](crate::models::ConfigId), for a configuration left out. A firmware image
/// built with one configuration feature then holds one configuration's code.
///
/// ```
/// use rollcal::models::{ConfigId, Model};
/// fn states<M: Model<N, Z>, const N: usize, const Z: usize>() -> Option<usize> {
///     Some(N)
/// }
/// let n = rollcal::with_built_config!(ConfigId::M1Pa, |M, N, Z| states::<M, N, Z>(), else |_other| None);
/// assert_eq!(n, Some(12));
/// ```
#[macro_export]
macro_rules! with_built_config {
    ($id:expr, |$m:ident, $n:ident, $z:ident| $body:expr, else |$other:ident| $fallback:expr) => {{
        let id: $crate::models::ConfigId = $id;
        'dispatch: {
            $crate::__rollcal_if_m1_pa! { if id == $crate::models::ConfigId::M1Pa { break 'dispatch $crate::with_config!(@arm M1Pa, 12, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m1_ps! { if id == $crate::models::ConfigId::M1Ps { break 'dispatch $crate::with_config!(@arm M1Ps, 15, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m2_ps! { if id == $crate::models::ConfigId::M2Ps { break 'dispatch $crate::with_config!(@arm M2Ps, 18, 6, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m3_pa! { if id == $crate::models::ConfigId::M3Pa { break 'dispatch $crate::with_config!(@arm M3Pa, 15, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m3_ps! { if id == $crate::models::ConfigId::M3Ps { break 'dispatch $crate::with_config!(@arm M3Ps, 18, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m4_pa! { if id == $crate::models::ConfigId::M4Pa { break 'dispatch $crate::with_config!(@arm M4Pa, 12, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m4_ps! { if id == $crate::models::ConfigId::M4Ps { break 'dispatch $crate::with_config!(@arm M4Ps, 15, 3, $m, $n, $z, $body); } }
            #[allow(unreachable_code)]
            {
                let $other = id;
                $fallback
            }
        }
    }};
}

/// [`with_config!`] with the error model: evaluates `body` with `M` the
/// model type of configuration `id` under error model `errors`
/// ([`ErrorModel`](crate::models::ErrorModel)) — `M2Ps` or `M2PsFull` —
/// and `N`, `Z` its state and measurement dimensions as `const`s. Every
/// one of the fourteen arms is instantiated, as [`with_config!`] does;
/// [`with_built_model!`] instantiates those of the configurations built.
///
/// [`with_built_model!`]: crate::with_built_model
///
/// ```
/// use rollcal::models::{ConfigId, ErrorModel, Model};
/// fn states<M: Model<N, Z>, const N: usize, const Z: usize>() -> (usize, usize) {
///     (N, M::states().len())
/// }
/// let n = rollcal::with_model!(ConfigId::M2Ps, ErrorModel::Full, |M, N, Z| states::<M, N, Z>());
/// assert_eq!(n, (54, 54));
/// let n = rollcal::with_model!(ConfigId::M2Ps, ErrorModel::Installation, |M, N, Z| states::<M, N, Z>());
/// assert_eq!(n, (18, 18));
/// ```
#[macro_export]
macro_rules! with_model {
    ($id:expr, $errors:expr, |$m:ident, $n:ident, $z:ident| $body:expr) => {
        match $errors {
            $crate::models::ErrorModel::Installation => $crate::with_config!($id, |$m, $n, $z| $body),
            $crate::models::ErrorModel::Full => match $id {
                $crate::models::ConfigId::M1Pa => $crate::with_config!(@arm M1PaFull, 48, 3, $m, $n, $z, $body),
                $crate::models::ConfigId::M1Ps => $crate::with_config!(@arm M1PsFull, 51, 3, $m, $n, $z, $body),
                $crate::models::ConfigId::M2Ps => $crate::with_config!(@arm M2PsFull, 54, 6, $m, $n, $z, $body),
                $crate::models::ConfigId::M3Pa => $crate::with_config!(@arm M3PaFull, 51, 3, $m, $n, $z, $body),
                $crate::models::ConfigId::M3Ps => $crate::with_config!(@arm M3PsFull, 54, 3, $m, $n, $z, $body),
                $crate::models::ConfigId::M4Pa => $crate::with_config!(@arm M4PaFull, 48, 3, $m, $n, $z, $body),
                $crate::models::ConfigId::M4Ps => $crate::with_config!(@arm M4PsFull, 51, 3, $m, $n, $z, $body),
            },
        }
    };
}

/// [`with_model!`] over the configurations and error models built into
/// this crate (cargo features `m1-pa` … `m4-ps` as [`with_built_config!`],
/// and `installation-model`, `full-model`): only their arms are
/// instantiated, and `fallback` is evaluated, with `other` the
/// [`ConfigId`](crate::models::ConfigId), for a configuration or an error
/// model left out (a flight image of the full model alone holds no
/// installation model's code).
///
/// ```
/// use rollcal::models::{ConfigId, ErrorModel, Model};
/// fn states<M: Model<N, Z>, const N: usize, const Z: usize>() -> Option<usize> {
///     Some(N)
/// }
/// let n = rollcal::with_built_model!(ConfigId::M4Pa, ErrorModel::Full, |M, N, Z| states::<M, N, Z>(), else |_other| None);
/// assert_eq!(n, Some(48));
/// ```
#[macro_export]
macro_rules! with_built_model {
    ($id:expr, $errors:expr, |$m:ident, $n:ident, $z:ident| $body:expr, else |$other:ident| $fallback:expr) => {{
        let id: $crate::models::ConfigId = $id;
        match $errors {
            $crate::models::ErrorModel::Installation => 'dispatch: {
                $crate::__rollcal_if_installation_model! {
                    break 'dispatch $crate::with_built_config!(id, |$m, $n, $z| $body, else |$other| $fallback);
                }
                #[allow(unreachable_code)]
                {
                    let $other = id;
                    $fallback
                }
            }
            $crate::models::ErrorModel::Full => 'dispatch: {
                $crate::__rollcal_if_full_model! {
                    $crate::__rollcal_if_m1_pa! { if id == $crate::models::ConfigId::M1Pa { break 'dispatch $crate::with_config!(@arm M1PaFull, 48, 3, $m, $n, $z, $body); } }
                    $crate::__rollcal_if_m1_ps! { if id == $crate::models::ConfigId::M1Ps { break 'dispatch $crate::with_config!(@arm M1PsFull, 51, 3, $m, $n, $z, $body); } }
                    $crate::__rollcal_if_m2_ps! { if id == $crate::models::ConfigId::M2Ps { break 'dispatch $crate::with_config!(@arm M2PsFull, 54, 6, $m, $n, $z, $body); } }
                    $crate::__rollcal_if_m3_pa! { if id == $crate::models::ConfigId::M3Pa { break 'dispatch $crate::with_config!(@arm M3PaFull, 51, 3, $m, $n, $z, $body); } }
                    $crate::__rollcal_if_m3_ps! { if id == $crate::models::ConfigId::M3Ps { break 'dispatch $crate::with_config!(@arm M3PsFull, 54, 3, $m, $n, $z, $body); } }
                    $crate::__rollcal_if_m4_pa! { if id == $crate::models::ConfigId::M4Pa { break 'dispatch $crate::with_config!(@arm M4PaFull, 48, 3, $m, $n, $z, $body); } }
                    $crate::__rollcal_if_m4_ps! { if id == $crate::models::ConfigId::M4Ps { break 'dispatch $crate::with_config!(@arm M4PsFull, 51, 3, $m, $n, $z, $body); } }
                }
                #[allow(unreachable_code)]
                {
                    let $other = id;
                    $fallback
                }
            }
        }
    }};
}
