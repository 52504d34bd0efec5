//! Why an executed file could not be measured: the metrics' one error type, below both the
//! measurement (`case`) and the plausibility check it runs first (`plausible`).

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricsError {
    /// The executed trajectory does not cover the plan's interval with at least two samples.
    #[error("the executed trajectory does not cover the plan interval [{t0:.3}, {t1:.3}] s")]
    Interval { t0: f64, t1: f64 },
    /// A value no rollout can produce, or a stored summary its steps contradict
    /// ([`crate::plausible`]).
    #[error("`{field}`: {message}")]
    Implausible { field: String, message: String },
}
