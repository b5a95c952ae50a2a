//! The OPC UA write → scan → read latency of a PLC (`cetratus bench opcua`): a client writes an
//! input and reads an output that the program sets from it, until the output follows.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use opcua::types::{AttributeId, DataValue, NodeId, ReadValueId, TimestampsToReturn, WriteValue};

use super::twin_client::{bool_of, client_error, connect, find_plc, ClientCounters};
use crate::IoError;

/// Toggles `<plc>.Inputs.<input>` `samples` times, each time reading `<plc>.Outputs.<output>`
/// until it shows the written value; the nanoseconds from sending the write to the read that
/// showed it. Samples are spaced by a pause that is not a multiple of any usual scan period, so
/// that they meet the cycle at every phase.
pub fn write_scan_read(
    url: &str,
    input: &str,
    output: &str,
    samples: usize,
) -> Result<Vec<u64>, IoError> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| IoError::Thread(e.to_string()))?;
    rt.block_on(async {
        let stop = AtomicBool::new(false);
        let mut counters = ClientCounters::default();
        let Some(session) = connect(url, &stop, &mut counters, &Default::default()).await? else {
            return Err(client_error("no session"));
        };
        let (ns, plc) = find_plc(&session).await?;
        let input = NodeId::new(ns, format!("{plc}.Inputs.{input}"));
        let output = [ReadValueId::new_value(NodeId::new(
            ns,
            format!("{plc}.Outputs.{output}"),
        ))];
        let mut out = Vec::with_capacity(samples);
        let mut v = false;
        for k in 0..samples {
            v = !v;
            let w = [WriteValue {
                node_id: input.clone(),
                attribute_id: AttributeId::Value as u32,
                index_range: Default::default(),
                value: DataValue::value_only(v),
            }];
            let t0 = Instant::now();
            let codes = session.write(&w).await.map_err(client_error)?;
            if let Some(c) = codes.iter().find(|c| !c.is_good()) {
                return Err(client_error(format!("the write was refused: {c}")));
            }
            loop {
                let got = session
                    .read(&output, TimestampsToReturn::Neither, 0.0)
                    .await
                    .map_err(client_error)?;
                if got.first().and_then(bool_of) == Some(v) {
                    break;
                }
                if t0.elapsed() > Duration::from_secs(2) {
                    return Err(client_error(
                        "the output did not follow the input within 2 s",
                    ));
                }
            }
            out.push(t0.elapsed().as_nanos() as u64);
            // 1.3 ms plus a little more each time: every phase of the cycle.
            tokio::time::sleep(Duration::from_micros(1_300 + (k as u64 * 137) % 1_000)).await;
        }
        let _ = session.disconnect().await;
        Ok(out)
    })
}
