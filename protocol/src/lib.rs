//! The Navtech Colossus TCP wire format. No IO, no clock.
