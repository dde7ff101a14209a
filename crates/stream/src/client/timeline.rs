//! Recorded client inputs: the calls a driver makes on a [`StreamClient`] (updates with their
//! camera, response heads, chunks, ends, errors) in order, so a timeline can be replayed.

use super::{Action, RequestId, StreamClient};
use splat2tiles_core::camera::Camera;

/// One call a driver made on a [`StreamClient`].
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// [`StreamClient::update`] at `t` with `camera`.
    Update {
        /// Seconds.
        t: f64,
        /// The camera passed.
        camera: Camera,
    },
    /// [`StreamClient::on_response`].
    Response {
        /// Request.
        id: RequestId,
        /// HTTP status.
        status: u16,
        /// `ETag` header.
        etag: Option<String>,
        /// Start of `Content-Range` (206).
        range_start: Option<u64>,
        /// Full length of the resource, when known.
        total: Option<u64>,
    },
    /// [`StreamClient::on_data`] at `t`.
    Data {
        /// Request.
        id: RequestId,
        /// Seconds.
        t: f64,
        /// The chunk.
        bytes: Vec<u8>,
    },
    /// [`StreamClient::on_done`] at `t`.
    Done {
        /// Request.
        id: RequestId,
        /// Seconds.
        t: f64,
    },
    /// [`StreamClient::on_error`] at `t`.
    Error {
        /// Request.
        id: RequestId,
        /// Seconds.
        t: f64,
        /// Transport message.
        message: String,
    },
}

impl Input {
    /// Makes the call on `client`; returns the actions of an `Update` (empty otherwise).
    pub fn apply(&self, client: &mut StreamClient) -> Vec<Action> {
        match self {
            Input::Update { t, camera } => return client.update(*t, camera),
            Input::Response {
                id,
                status,
                etag,
                range_start,
                total,
            } => client.on_response(*id, *status, etag.as_deref(), *range_start, *total),
            Input::Data { id, t, bytes } => client.on_data(*id, bytes, *t),
            Input::Done { id, t } => client.on_done(*id, *t),
            Input::Error { id, t, message } => client.on_error(*id, message, *t),
        }
        vec![]
    }
}

/// Replays `inputs` through `client`: the actions of each `Update`, in order.
pub fn replay(client: &mut StreamClient, inputs: &[Input]) -> Vec<Vec<Action>> {
    let mut out = vec![];
    for i in inputs {
        let a = i.apply(client);
        if matches!(i, Input::Update { .. }) {
            out.push(a);
        }
    }
    out
}
