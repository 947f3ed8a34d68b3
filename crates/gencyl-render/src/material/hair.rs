//! The hair BSDF of Chiang et al. 2016 (placeholder; being written).
