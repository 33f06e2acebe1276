//! One pad from its converter readings to everything the device reports about it: the pressure
//! model ([`PadModel`]), then the pad's force and centre of pressure on its geometry
//! ([`crate::pad_force`]), then contact ([`crate::contact`]). The device, the host's conversion
//! of a recording and the Python package run this one pipeline, so a recording re-processed with
//! the device's state gives the device's force, centre of pressure and contact.
//!
//! The device reads a pad's converter inside its acquisition loop, which runs the model; it then
//! hands the model's output to the pad's [`ForceAndContact`], the second half of the pipeline.
//! A host holds a whole [`PadPipeline`].

use crate::calibration::TAXEL_COUNT;
use crate::contact::{ContactConfig, ContactDetector, ContactEvent};
use crate::pad::{PadModel, PadOutput, SampleInput};
use crate::pad_force::{pad_force, PadForce, PadForceFlags};
use crate::pad_geometry::{PadGeometry, PadRole};
use crate::taxel::TaxelOutput;

/// What a pad reports beyond its pressures for one sample set.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadContact {
    /// Force and centre of pressure on the taxels that read.
    pub force: PadForce,
    /// The pad is in contact after this set.
    pub in_contact: bool,
    /// The change of contact this set confirmed, if any.
    pub event: Option<ContactEvent>,
}

impl PadContact {
    /// Force in N (`None`: no taxel reads).
    pub fn force_n(&self) -> Option<f32> {
        self.force.force_n
    }

    /// Centre of pressure (x, y) in mm (`None`: no force, or too little to place it).
    pub fn centre_of_pressure_mm(&self) -> Option<[f32; 2]> {
        self.force
            .centre_of_pressure_mm
            .map(|(x_mm, y_mm)| [x_mm, y_mm])
    }

    /// Some taxels were left out of force and centre of pressure because they are faulted.
    pub fn partial(&self) -> bool {
        self.force.flags.contains(PadForceFlags::PARTIAL)
    }
}

/// The second half of the pipeline: a pad's geometry and role, and its contact detector.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ForceAndContact {
    role: PadRole,
    geometry: PadGeometry,
    contact: ContactDetector,
}

impl ForceAndContact {
    /// A pad of `geometry` and `role`, out of contact, detecting contact with `contact`.
    pub fn new(role: PadRole, geometry: PadGeometry, contact: ContactConfig) -> Self {
        Self {
            role,
            geometry,
            contact: ContactDetector::new(contact),
        }
    }

    /// What the pad is.
    pub fn role(&self) -> PadRole {
        self.role
    }

    /// The taxels' centres and areas.
    pub fn geometry(&self) -> &PadGeometry {
        &self.geometry
    }

    /// Another geometry and role from the next set on (the contact state is kept).
    pub fn set_geometry(&mut self, role: PadRole, geometry: PadGeometry) {
        self.role = role;
        self.geometry = geometry;
    }

    /// True while in contact.
    pub fn in_contact(&self) -> bool {
        self.contact.in_contact()
    }

    /// Takes the contact state as `in_contact`, with nothing pending: for a host that starts
    /// reading a stream whose device was already in contact (its first frame's contact bit).
    pub fn assume_contact(&mut self, in_contact: bool, force: &PadForce) {
        self.contact.assume(in_contact, force);
    }

    /// Force, centre of pressure and contact of one set's taxel outputs, measured at
    /// `timestamp_us` on the device clock.
    pub fn update(&mut self, taxels: &[TaxelOutput; TAXEL_COUNT], timestamp_us: u64) -> PadContact {
        let force = pad_force(taxels, &self.geometry);
        let event = self.contact.update(&force, timestamp_us);
        PadContact {
            force,
            in_contact: self.contact.in_contact(),
            event,
        }
    }
}

/// A pad's whole pipeline's result for one sample set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadReport {
    /// The model's output: pressures, flags and the temperature used.
    pub output: PadOutput,
    /// Force, centre of pressure and contact.
    pub contact: PadContact,
}

/// One pad's whole pipeline: model, geometry, contact.
#[derive(Debug, Clone)]
pub struct PadPipeline {
    model: PadModel,
    force_and_contact: ForceAndContact,
}

impl PadPipeline {
    /// `model`, then force and contact by `force_and_contact`.
    pub fn new(model: PadModel, force_and_contact: ForceAndContact) -> Self {
        Self {
            model,
            force_and_contact,
        }
    }

    /// The pressure model.
    pub fn model(&self) -> &PadModel {
        &self.model
    }

    /// The pressure model, to tare or configure.
    pub fn model_mut(&mut self) -> &mut PadModel {
        &mut self.model
    }

    /// Geometry and contact.
    pub fn force_and_contact(&self) -> &ForceAndContact {
        &self.force_and_contact
    }

    /// Geometry and contact, to configure.
    pub fn force_and_contact_mut(&mut self) -> &mut ForceAndContact {
        &mut self.force_and_contact
    }

    /// The model and the second half, each borrowed on its own.
    #[cfg(feature = "batch")]
    pub(crate) fn parts_mut(&mut self) -> (&mut PadModel, &mut ForceAndContact) {
        (&mut self.model, &mut self.force_and_contact)
    }

    /// One sample set through the whole pipeline. Contact events carry the sample's time (0 for
    /// a sample without one).
    pub fn process(&mut self, sample: &SampleInput) -> PadReport {
        let output = self.model.process(sample);
        let contact = self
            .force_and_contact
            .update(&output.taxels, sample.time_us.unwrap_or(0));
        PadReport { output, contact }
    }
}
