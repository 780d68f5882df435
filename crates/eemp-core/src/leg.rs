//! Legs are named, never indexed by magic numbers.

use std::ops::{Index, IndexMut};

/// One of the four legs, in Unitree's actuator order (FR, FL, RR, RL).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Leg {
    FrontRight,
    FrontLeft,
    RearRight,
    RearLeft,
}

impl Leg {
    /// All legs in actuator order.
    pub const ALL: [Leg; 4] = [
        Leg::FrontRight,
        Leg::FrontLeft,
        Leg::RearRight,
        Leg::RearLeft,
    ];

    /// Position in actuator order (0..4); the only place the order is spelled out.
    pub const fn index(self) -> usize {
        match self {
            Leg::FrontRight => 0,
            Leg::FrontLeft => 1,
            Leg::RearRight => 2,
            Leg::RearLeft => 3,
        }
    }

    /// +1 for front legs, −1 for rear legs (sign of the hip's x in the body frame).
    pub const fn front_sign(self) -> f64 {
        match self {
            Leg::FrontRight | Leg::FrontLeft => 1.0,
            Leg::RearRight | Leg::RearLeft => -1.0,
        }
    }

    /// +1 for left legs, −1 for right legs (sign of the hip's y in the body frame).
    pub const fn side_sign(self) -> f64 {
        match self {
            Leg::FrontLeft | Leg::RearLeft => 1.0,
            Leg::FrontRight | Leg::RearRight => -1.0,
        }
    }

    /// The diagonally opposite leg (its trot partner).
    pub const fn diagonal(self) -> Leg {
        match self {
            Leg::FrontRight => Leg::RearLeft,
            Leg::FrontLeft => Leg::RearRight,
            Leg::RearRight => Leg::FrontLeft,
            Leg::RearLeft => Leg::FrontRight,
        }
    }

    /// The leg on the other side (the left–right mirror's partner).
    pub const fn mirror(self) -> Leg {
        match self {
            Leg::FrontRight => Leg::FrontLeft,
            Leg::FrontLeft => Leg::FrontRight,
            Leg::RearRight => Leg::RearLeft,
            Leg::RearLeft => Leg::RearRight,
        }
    }

    /// Short name used in files and MuJoCo names: "FR", "FL", "RR", "RL".
    pub const fn short_name(self) -> &'static str {
        match self {
            Leg::FrontRight => "FR",
            Leg::FrontLeft => "FL",
            Leg::RearRight => "RR",
            Leg::RearLeft => "RL",
        }
    }
}

/// A value per leg, indexed by [`Leg`].
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LegMap<T>(pub [T; 4]);

impl<T> LegMap<T> {
    pub fn from_fn(mut f: impl FnMut(Leg) -> T) -> Self {
        LegMap(Leg::ALL.map(&mut f))
    }
    pub fn iter(&self) -> impl Iterator<Item = (Leg, &T)> {
        Leg::ALL.into_iter().zip(self.0.iter())
    }
    pub fn map<U>(&self, mut f: impl FnMut(Leg, &T) -> U) -> LegMap<U> {
        LegMap::from_fn(|leg| f(leg, &self[leg]))
    }
}

impl<T: Copy> LegMap<T> {
    pub fn splat(value: T) -> Self {
        LegMap([value; 4])
    }
}

impl<T> Index<Leg> for LegMap<T> {
    type Output = T;
    fn index(&self, leg: Leg) -> &T {
        &self.0[leg.index()]
    }
}

impl<T> IndexMut<Leg> for LegMap<T> {
    fn index_mut(&mut self, leg: Leg) -> &mut T {
        &mut self.0[leg.index()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_matches_all_order_and_diagonals_pair_up() {
        for (i, leg) in Leg::ALL.into_iter().enumerate() {
            assert_eq!(leg.index(), i);
            assert_eq!(leg.diagonal().diagonal(), leg);
            assert_ne!(leg.diagonal().side_sign(), leg.side_sign());
            assert_ne!(leg.diagonal().front_sign(), leg.front_sign());
        }
    }
}
