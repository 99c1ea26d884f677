//! Foxglove's Parameters capability on the live tuner (issue 36, docs/parameters.md): a
//! client's `getParameters` lists every parameter of the console's panel by name with its
//! value in force (float64), and `setParameters` changes them through the same
//! [`crate::tuning::Shared::set`], with the same ranges and the same bumpless application. A
//! refused value (out of range, not a number, an unknown name) changes nothing: the client
//! gets an error status naming the parameter and its range, and the value in force back.
//!
//! The `foxglove` crate (0.30.3) calls the handler from its connection tasks with a responder
//! that must be answered (`remote_common/parameters.rs`, `ParameterHandler`); the crate's
//! `connected_client.rs` (`on_get_parameters`, `on_set_parameters`) routes both requests here
//! once the server has `Capability::Parameters` and a parameter handler.

use ::foxglove::websocket::{
    AnyClient, GetParametersResponder, Parameter, ParameterHandler, ParameterValue,
    SetParametersResponder,
};

use crate::tuning::TuningHandle;

/// The handler the server is given.
pub struct LiveParameters(pub TuningHandle);

impl LiveParameters {
    /// The named parameters (all, when `names` is empty) with their values in force.
    fn values(&self, names: &[String]) -> Vec<Parameter> {
        let Ok(shared) = self.0.lock() else {
            return Vec::new();
        };
        let t = &shared.tuner;
        t.parameters()
            .iter()
            .enumerate()
            .filter(|(_, p)| names.is_empty() || names.contains(&p.name))
            .map(|(i, p)| Parameter::float64(p.name.clone(), t.value(i)))
            .collect()
    }
}

/// A parameter's value as a number, if it is one.
fn number(p: &Parameter) -> Option<f64> {
    match p.value {
        Some(ParameterValue::Float64(v)) => Some(v),
        Some(ParameterValue::Integer(i)) => Some(i as f64),
        _ => None,
    }
}

impl ParameterHandler for LiveParameters {
    fn get(
        &self,
        _client: AnyClient,
        names: Vec<String>,
        _request_id: Option<String>,
        responder: GetParametersResponder,
    ) {
        responder.respond(self.values(&names));
    }

    fn set(
        &self,
        client: AnyClient,
        parameters: Vec<Parameter>,
        _request_id: Option<String>,
        responder: SetParametersResponder,
    ) {
        let names: Vec<String> = parameters.iter().map(|p| p.name.clone()).collect();
        if let Ok(mut shared) = self.0.lock() {
            for p in &parameters {
                let outcome = match number(p) {
                    Some(v) => shared.set(&p.name, v).map_err(|e| e.to_string()),
                    None => Err(format!(
                        "`{}`: expected a number (float64), got {:?}: nothing changed",
                        p.name, p.value
                    )),
                };
                if let Err(message) = outcome {
                    client.send_error(message);
                }
            }
        }
        responder.respond(self.values(&names));
    }
}
