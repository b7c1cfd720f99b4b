//! The environment a scene puts its robot in, beside the robot itself ([`Environment`]): gravity
//! and the contact material of its declared contacts ([`ContactMaterial`], docs/contacts.md §2–§3)
//! with their defaults. A ground-floor module: the scene makes an environment
//! (`Scene::environment`), parameters (`scene.gravity.*`, `scene.contact.*`) override its values
//! per sample, the dynamics take its gravity and the effects its material as arguments, and
//! `model/` (the robot alone) knows nothing of it.

use crate::spatial::Vec3;

/// Standard gravity used when nothing else is said (m/s², along −z).
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// What surrounds the robot in a scene: the values a scene (and parameters) set that are not the
/// robot's own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment {
    /// Gravity in the world frame (m/s²); zero when the scene does not declare the gravity effect.
    pub gravity: Vec3,
    /// The contact material of the scene (`[scene.contact]`), `None` when the scene declares no
    /// contacts.
    pub contact: Option<ContactMaterial>,
}

impl Default for Environment {
    /// [`DEFAULT_GRAVITY`] and no contacts.
    fn default() -> Self {
        Self {
            gravity: Vec3::from(DEFAULT_GRAVITY),
            contact: None,
        }
    }
}

/// Contact material of a scene: Hunt–Crossley normal force and regularised Coulomb friction
/// (docs/contacts.md §2–§3). One material for every declared pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactMaterial {
    /// `k` of `f_n = k δ^e (1 + d δ̇)`, N/m^e (N/m^1.5 for the Hertz exponent).
    pub stiffness: f64,
    /// Exponent `e` of the penetration (1.5: Hertz; 1: linear), unitless, ≥ 1.
    pub exponent: f64,
    /// Hunt–Crossley dissipation `d`, s/m (restitution `e(v)` from docs/contacts.md §2).
    pub damping: f64,
    /// Coulomb friction coefficient `μ`, unitless, ≥ 0.
    pub friction: f64,
    /// Stiction velocity `v_s` of the regularised friction `−μ f_n v_t / √(|v_t|² + v_s²)`, m/s.
    pub stiction_velocity: f64,
}

/// Default contact stiffness, N/m^1.5: a 1 kg body rests on a sphere of it about 0.2 mm deep
/// (`(m g / k)^(2/3)`), Drake's default penetration allowance is 1 mm.
pub const DEFAULT_CONTACT_STIFFNESS: f64 = 1e6;
/// Default Hunt–Crossley exponent (Hertz contact of a sphere).
pub const DEFAULT_CONTACT_EXPONENT: f64 = 1.5;
/// Default Hunt–Crossley dissipation, s/m: restitution ≈ 0.6 at 1 m/s (docs/contacts.md §2);
/// Drake documents values of order 1 s/m for its point contact's `hunt_crossley_dissipation`.
pub const DEFAULT_CONTACT_DAMPING: f64 = 0.5;
/// Default friction coefficient (Chrono's default static and sliding friction, 0.6).
pub const DEFAULT_CONTACT_FRICTION: f64 = 0.6;
/// Default stiction velocity, m/s (Drake's default stiction tolerance is 1e-3 m/s; ribbon's
/// implicit integrator affords ten times less creep).
pub const DEFAULT_STICTION_VELOCITY: f64 = 1e-4;

impl Default for ContactMaterial {
    fn default() -> Self {
        Self {
            stiffness: DEFAULT_CONTACT_STIFFNESS,
            exponent: DEFAULT_CONTACT_EXPONENT,
            damping: DEFAULT_CONTACT_DAMPING,
            friction: DEFAULT_CONTACT_FRICTION,
            stiction_velocity: DEFAULT_STICTION_VELOCITY,
        }
    }
}
