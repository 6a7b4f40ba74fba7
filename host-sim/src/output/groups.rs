//! The names of the state groups in figures and reports, one place for
//! every figure title and report section.

use rollcal::models::Group;

/// What a group is, in words with its symbol (`accelerometer bias ba`); a
/// group without words here is named by its JSON name.
pub fn title(g: Group) -> String {
    match g {
        Group::ThetaAT => "accelerometer non-orthogonality θaT".into(),
        Group::ThetaAC => "accelerometer axis rotation θaC".into(),
        Group::ThetaGT => "gyro non-orthogonality θgT".into(),
        Group::ThetaGC => "gyro axis rotation θgC".into(),
        Group::Lambda => "base mounting λ".into(),
        Group::Attitude => "attitude".into(),
        Group::GyroDrift => "gyro drift dg".into(),
        Group::GyroGDrift => "g-sensitive gyro drift Dg".into(),
        Group::GyroScale => "gyro scale factor kg".into(),
        Group::AccelBias => "accelerometer bias ba".into(),
        Group::AccelScale => "accelerometer scale factor ka".into(),
        Group::AccelSecondOrder => "accelerometer second-order term k2".into(),
        Group::GyroMarkov => "Gauss–Markov part of the gyro drift".into(),
        Group::AccelMarkov => "Gauss–Markov part of the accelerometer bias".into(),
        Group::GyroWarmup => "warm-up of the gyro drift".into(),
        Group::AccelWarmup => "warm-up of the accelerometer bias".into(),
    }
}

/// The groups of `states` in order of first appearance.
pub fn in_order(states: impl IntoIterator<Item = Group>) -> Vec<Group> {
    let mut out: Vec<Group> = Vec::new();
    for g in states {
        if !out.contains(&g) {
            out.push(g);
        }
    }
    out
}
