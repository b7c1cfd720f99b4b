//! The environment a scene puts its robot in, beside the robot itself: the contact material of
//! its declared contacts ([`ContactMaterial`], docs/contacts.md §2–§3) with its defaults. Gravity
//! is the model's (`Model::gravity`, as in Pinocchio: the dynamics read it). A ground-floor module:
//! `model` holds a scene's material for parameters to override (`Model::contact`), `geometry`
//! and `effects` compute with it, and neither depends on the other for it.

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
