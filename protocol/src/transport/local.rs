//! In-process transport for unit tests: every endpoint of a `LocalHub` gets one channel; a
//! publisher copies its bytes into the channel of every endpoint subscribed to the topic.

use super::{Publisher, TopicId, Transport, TransportError};
use std::collections::HashMap;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

type Subscribers = HashMap<String, Vec<(Sender<(String, Vec<u8>)>, String)>>;

/// Shared routing table of one in-process run.
#[derive(Clone, Default)]
pub struct LocalHub {
    subs: Arc<Mutex<Subscribers>>,
}

impl LocalHub {
    pub fn new() -> Self {
        Self::default()
    }

    /// A new endpoint on this hub.
    pub fn endpoint(&self, name: &str) -> LocalTransport {
        let (tx, rx) = channel();
        LocalTransport {
            hub: self.clone(),
            name: name.to_string(),
            tx,
            rx,
            topics: Vec::new(),
        }
    }
}

pub struct LocalTransport {
    hub: LocalHub,
    name: String,
    tx: Sender<(String, Vec<u8>)>,
    rx: Receiver<(String, Vec<u8>)>,
    topics: Vec<String>,
}

struct LocalPublisher {
    hub: LocalHub,
    topic: String,
}

impl Publisher for LocalPublisher {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let subs = self.hub.subs.lock().map_err(|_| TransportError::Send {
            topic: self.topic.clone(),
            reason: "hub lock poisoned".into(),
        })?;
        if let Some(list) = subs.get(&self.topic) {
            for (tx, _) in list {
                // A receiver that has gone away is not an error for the sender.
                let _ = tx.send((self.topic.clone(), bytes.to_vec()));
            }
        }
        Ok(())
    }
}

impl Transport for LocalTransport {
    fn publisher(
        &mut self,
        topic: &str,
        _readers: &[String],
    ) -> Result<Box<dyn Publisher>, TransportError> {
        Ok(Box::new(LocalPublisher {
            hub: self.hub.clone(),
            topic: topic.to_string(),
        }))
    }

    fn subscribe(&mut self, topic: &str) -> Result<TopicId, TransportError> {
        let mut subs = self
            .hub
            .subs
            .lock()
            .map_err(|_| TransportError::Setup("hub lock poisoned".into()))?;
        subs.entry(topic.to_string())
            .or_default()
            .push((self.tx.clone(), self.name.clone()));
        self.topics.push(topic.to_string());
        Ok(self.topics.len() - 1)
    }

    fn recv(
        &mut self,
        timeout: Duration,
        f: &mut dyn FnMut(TopicId, &[u8]),
    ) -> Result<bool, TransportError> {
        match self.rx.recv_timeout(timeout) {
            Ok((topic, bytes)) => {
                let id = self
                    .topics
                    .iter()
                    .position(|t| *t == topic)
                    .ok_or_else(|| {
                        TransportError::Recv(format!("message on unknown topic {topic}"))
                    })?;
                f(id, &bytes);
                Ok(true)
            }
            Err(RecvTimeoutError::Timeout) => Ok(false),
            Err(RecvTimeoutError::Disconnected) => Err(TransportError::Recv("hub closed".into())),
        }
    }

    fn readers(&self, topic: &str) -> Option<usize> {
        self.hub
            .subs
            .lock()
            .ok()
            .map(|s| s.get(topic).map_or(0, |l| l.len()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_reaches_every_subscriber_in_order() {
        let hub = LocalHub::new();
        let mut a = hub.endpoint("a");
        let mut b = hub.endpoint("b");
        let mut c = hub.endpoint("c");
        b.subscribe("t").unwrap();
        c.subscribe("t").unwrap();
        let mut p = a.publisher("t", &["b".into(), "c".into()]).unwrap();
        p.send(&[1, 2]).unwrap();
        p.send(&[3]).unwrap();
        for ep in [&mut b, &mut c] {
            let mut got = Vec::new();
            while ep
                .recv(Duration::from_millis(10), &mut |_, x| got.push(x.to_vec()))
                .unwrap()
            {}
            assert_eq!(got, vec![vec![1, 2], vec![3]]);
        }
    }
}
