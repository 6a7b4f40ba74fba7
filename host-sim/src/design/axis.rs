//! The n-frame rotation axes of a path, named (`north`, `up`, …) or tilted
//! half-way between two of them (`north+up`).

use crate::sim::scenario::Axis;

use super::DesignError;

/// One n-frame rotation axis with its name.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct NamedAxis {
    /// `north`, `up`, … or `north+up` for a tilted axis.
    pub name: String,
    /// Unit vector in n (North, Up, East).
    pub unit: [f64; 3],
}

impl NamedAxis {
    /// One of the six named n-frame directions.
    pub fn named(name: &str) -> Result<Self, DesignError> {
        let unit = Axis::Named(name.to_string())
            .unit()
            .map_err(|e| DesignError::Axis(e.to_string()))?;
        Ok(Self {
            name: name.to_ascii_lowercase(),
            unit,
        })
    }

    /// The axis half-way between two perpendicular axes.
    pub fn tilted(a: &NamedAxis, b: &NamedAxis) -> Self {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        Self {
            name: format!("{}+{}", a.name, b.name),
            unit: [
                (a.unit[0] + b.unit[0]) * s,
                (a.unit[1] + b.unit[1]) * s,
                (a.unit[2] + b.unit[2]) * s,
            ],
        }
    }

    pub(super) fn dot(&self, o: &NamedAxis) -> f64 {
        self.unit[0] * o.unit[0] + self.unit[1] * o.unit[1] + self.unit[2] * o.unit[2]
    }

    /// The scenario-file form: the name for the six directions, else the
    /// vector.
    pub fn to_axis(&self) -> Axis {
        if self.name.contains('+') {
            Axis::Vector(self.unit)
        } else {
            Axis::Named(self.name.clone())
        }
    }
}
