//! A simulated Navtech radar serving synthetic spectra over the Colossus protocol.
