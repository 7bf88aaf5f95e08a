//! LuGre friction at one fingertip, scaled by the normal force.

use super::object::FrictionConfig;

/// The bristle state of one contact.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LuGreContact {
    /// Mean bristle deflection `z` (m).
    pub z_m: f64,
    /// Its rate `dz/dt` over the last step (m/s).
    pub z_rate_mps: f64,
}

/// Coefficients of one contact for the current trial (jittered, profile applied).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LuGreParams {
    /// Static coefficient `mu_s`.
    pub mu_static: f64,
    /// Kinetic coefficient `mu_k`.
    pub mu_kinetic: f64,
    /// Stribeck velocity (m/s).
    pub stribeck_mps: f64,
    /// `sigma0` (1/m).
    pub sigma0_per_m: f64,
    /// `sigma1` (s/m).
    pub sigma1_s_per_m: f64,
    /// `sigma2` (s/m).
    pub sigma2_s_per_m: f64,
}

impl LuGreParams {
    /// From the object's friction, with the coefficients multiplied by `scale`.
    pub fn from_config(f: &FrictionConfig, scale: f64) -> LuGreParams {
        LuGreParams {
            mu_static: f.mu_static * scale,
            mu_kinetic: f.mu_kinetic * scale,
            stribeck_mps: f.stribeck_velocity_mps,
            sigma0_per_m: f.bristle_stiffness_per_m,
            sigma1_s_per_m: f.bristle_damping_s_per_m,
            sigma2_s_per_m: f.viscous_s_per_m,
        }
    }

    /// The Stribeck curve `g(v)` (dimensionless), times `scale` (position profile).
    pub fn stribeck(&self, v_mps: f64, scale: f64) -> f64 {
        let r = v_mps / self.stribeck_mps;
        scale * (self.mu_kinetic + (self.mu_static - self.mu_kinetic) * (-r * r).exp())
    }
}

impl LuGreContact {
    /// Advances the bristles over `dt_s` at the constant slip velocity `v_mps`.
    ///
    /// `dz/dt = v - a z` with `a = sigma0 |v| / g(v)` is linear in `z` for a
    /// constant `v`, so the step is exact (stable at any step size):
    /// `z(dt) = z_ss + (z - z_ss) exp(-a dt)`, `z_ss = v / a`.
    pub fn step(&mut self, p: &LuGreParams, v_mps: f64, g: f64, dt_s: f64) {
        let z0 = self.z_m;
        let a = p.sigma0_per_m * v_mps.abs() / g;
        if a * dt_s < 1e-12 {
            self.z_m = z0 + v_mps * dt_s;
        } else {
            let z_ss = v_mps / a;
            self.z_m = z_ss + (z0 - z_ss) * (-a * dt_s).exp();
        }
        self.z_rate_mps = (self.z_m - z0) / dt_s;
    }

    /// Friction force (N) opposing a positive slip, for normal force `normal_n`.
    pub fn force(&self, p: &LuGreParams, v_mps: f64, normal_n: f64) -> f64 {
        normal_n * (p.sigma0_per_m * self.z_m + p.sigma1_s_per_m * self.z_rate_mps + p.sigma2_s_per_m * v_mps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> LuGreParams {
        LuGreParams {
            mu_static: 0.6,
            mu_kinetic: 0.4,
            stribeck_mps: 0.002,
            sigma0_per_m: 2000.0,
            sigma1_s_per_m: 10.0,
            sigma2_s_per_m: 5.0,
        }
    }

    #[test]
    fn steady_sliding_gives_coulomb_plus_viscous_friction() {
        let p = params();
        let mut c = LuGreContact::default();
        let v = 0.01;
        for _ in 0..2000 {
            c.step(&p, v, p.stribeck(v, 1.0), 1e-3);
        }
        // Closed form of the steady state: F = F_n (g(v) + sigma2 v).
        let expected = 2.0 * (p.stribeck(v, 1.0) + p.sigma2_s_per_m * v);
        assert!((c.force(&p, v, 2.0) - expected).abs() < 1e-9, "{}", c.force(&p, v, 2.0));
    }

    #[test]
    fn presliding_is_elastic_below_breakaway() {
        // A tiny displacement loads the bristles as a spring of stiffness F_n sigma0.
        let p = params();
        let mut c = LuGreContact::default();
        let (v, dt) = (1e-5, 1e-3);
        for _ in 0..10 {
            c.step(&p, v, p.stribeck(v, 1.0), dt);
        }
        let x = v * 10.0 * dt;
        assert!((c.z_m - x).abs() / x < 1e-3, "z {} vs displacement {}", c.z_m, x);
    }

    #[test]
    fn stribeck_curve_goes_from_static_to_kinetic() {
        let p = params();
        assert!((p.stribeck(0.0, 1.0) - 0.6).abs() < 1e-12);
        assert!((p.stribeck(0.1, 1.0) - 0.4).abs() < 1e-9);
        assert!((p.stribeck(0.0, 0.5) - 0.3).abs() < 1e-12);
    }
}
