//! Real iceoryx2 services between ports of one process.

use messages::*;

fn prefix(test: &str) -> String {
    format!("gema2test_{}_{}", test, std::process::id())
}

/// What a stage reading scans holds: the scan topic under the test's prefix, a subscriber and
/// a listener on it.
struct ScanReader {
    prefix: String,
    node: iceoryx2::prelude::Node<iceoryx2::prelude::ipc::Service>,
    topic: TopicPorts<ScanMsg>,
    sub: iceoryx2::port::subscriber::Subscriber<iceoryx2::prelude::ipc::Service, ScanMsg, ()>,
    listener: iceoryx2::port::listener::Listener<iceoryx2::prelude::ipc::Service>,
}

fn scan_reader(test: &str) -> ScanReader {
    let prefix = prefix(test);
    let node = create_node("test").unwrap();
    let topic = open_topic::<ScanMsg>(&node, &prefix, Topic::Scan).unwrap();
    let sub = topic.data.subscriber_builder().create().unwrap();
    let listener = topic.event.listener_builder().create().unwrap();
    ScanReader { prefix, node, topic, sub, listener }
}

#[test]
fn a_scan_goes_through_shared_memory_and_wakes_the_listener() {
    let ScanReader { node: _node, topic, sub, listener, .. } = scan_reader("scan");
    let publisher = topic.data.publisher_builder().create().unwrap();
    let notifier = topic.event.notifier_builder().create().unwrap();
    let delivered = publish(&publisher, &notifier, |m: &mut ScanMsg| {
        m.header = Header::new(7, monotonic_ns());
        m.header.set_producer("sim");
        m.count = 3;
        m.ranges[..3].copy_from_slice(&[1.0, 2.0, 3.0]);
    })
    .unwrap();
    assert_eq!(delivered, 1);
    let mut woke = 0;
    listener.timed_wait(|_| woke += 1, std::time::Duration::from_secs(1)).unwrap();
    assert!(woke >= 1);
    let sample = sub.receive().unwrap().unwrap();
    assert_eq!(sample.header.seq, 7);
    assert_eq!(sample.header.producer(), "sim");
    assert_eq!(&sample.ranges[..3], &[1.0, 2.0, 3.0]);
    assert!(sample.ranges[3..].iter().all(|&r| r == 0.0));
}

#[test]
fn a_payload_type_mismatch_is_an_error_naming_the_service() {
    let p = prefix("mismatch");
    let node = create_node("test").unwrap();
    let wrong = open_topic::<PoseMsg>(&node, &p, Topic::Scan).err().unwrap().to_string();
    assert!(wrong.contains(&format!("{p}/scan")) && wrong.contains("ScanMsg") && wrong.contains("PoseMsg"), "{wrong}");
    // a service created by someone else with another payload type
    let _scan = open_topic::<ScanMsg>(&node, &p, Topic::Scan).unwrap();
    let clash =
        open_pubsub::<PoseMsg>(&node, &service_name(&p, "scan"), Topic::Scan.settings()).err().unwrap().to_string();
    assert!(clash.contains(&format!("{p}/scan")) && clash.contains("IncompatibleTypes"), "{clash}");
}

#[test]
fn the_map_reaches_a_late_subscriber_through_history() {
    let p = prefix("late");
    let node = create_node("test").unwrap();
    let topic = open_topic::<MapMsg>(&node, &p, Topic::Map).unwrap();
    let publisher = topic.data.publisher_builder().create().unwrap();
    let notifier = topic.event.notifier_builder().create().unwrap();
    publish(&publisher, &notifier, |m: &mut MapMsg| {
        m.version = 3;
        m.count = 1;
        m.walls[0] = [0.0, 0.0, 1.0, 0.0];
    })
    .unwrap();
    let late = topic.data.subscriber_builder().create().unwrap();
    use messages::iceoryx2::port::update_connections::UpdateConnections;
    publisher.update_connections().unwrap();
    let sample = late.receive().unwrap().expect("history delivered");
    assert_eq!((sample.version, sample.count), (3, 1));
}

/// A publisher that appears after its subscriber and sends more than the subscriber's buffer
/// holds before the subscriber first looks: iceoryx2 drops what finds the unconnected buffer
/// full, so the outlet sends it again once the subscriber connects, and the subscriber takes
/// each scan once.
#[test]
fn an_outlet_loses_nothing_to_a_subscriber_that_connects_late() {
    use iceoryx2::prelude::BackpressureStrategy;
    use std::sync::mpsc;
    use std::time::{Duration, Instant};
    let p = prefix("late");
    let total = 2 * Topic::Scan.settings().buffer as u64 + 10;
    let (created, subscribed) = mpsc::channel();
    let q = p.clone();
    let taker = std::thread::spawn(move || {
        let node = create_node("taker").unwrap();
        let topic = open_topic::<ScanMsg>(&node, &q, Topic::Scan).unwrap();
        let sub = topic.data.subscriber_builder().create().unwrap();
        created.send(()).unwrap();
        // busy elsewhere while the publisher appears and fills the buffer
        std::thread::sleep(Duration::from_millis(300));
        let (mut fresh, mut seqs) = (Freshness::default(), Vec::new());
        let deadline = Instant::now() + Duration::from_secs(20);
        while (seqs.len() as u64) < total && Instant::now() < deadline {
            match sub.receive().unwrap() {
                Some(s) if fresh.admit(&s.header) => seqs.push(s.header.seq),
                Some(_) => {}
                None => std::thread::sleep(Duration::from_millis(1)),
            }
        }
        seqs
    });
    subscribed.recv().unwrap();
    let node = create_node("giver").unwrap();
    let mut out = Outlet::<ScanMsg>::open(&node, &p, Topic::Scan, BackpressureStrategy::RetryUntilDelivered).unwrap();
    for seq in 0..total {
        let stamp = monotonic_ns();
        let delivered = out.send(|m: &mut ScanMsg| m.header = Header::new(seq, stamp)).unwrap();
        assert_eq!(delivered, 1, "scan {seq}");
    }
    let seqs = taker.join().unwrap();
    assert_eq!(seqs, (0..total).collect::<Vec<_>>());
    assert!(out.resent > 0, "the buffer never filled before the subscriber connected: the test tests nothing");
    assert_eq!(out.missed, 0);
}

/// A warm-up wakes the topic's listener without a message, and a stage's drain tells it from a
/// message's notification.
#[test]
fn a_warm_up_wakes_the_listener_with_no_message() {
    use iceoryx2::prelude::BackpressureStrategy;
    let ScanReader { prefix, node, sub, listener, .. } = scan_reader("warm");
    let mut out = Outlet::<ScanMsg>::open(&node, &prefix, Topic::Scan, BackpressureStrategy::DiscardData).unwrap();

    out.warm_up().unwrap();
    let mut woke = false;
    listener.timed_wait(|e| woke |= e.id == WARM_UP, std::time::Duration::from_secs(1)).unwrap();
    assert!(woke, "the warm-up did not wake the listener");
    assert!(sub.receive().unwrap().is_none(), "a warm-up carries no message");

    out.warm_up().unwrap();
    let mut drain = ListenerDrain::new([&listener]);
    drain.once();
    assert!(drain.warm_up_to_pass_on());

    out.send(|m: &mut ScanMsg| m.header = Header::new(1, monotonic_ns())).unwrap();
    let mut drain = ListenerDrain::new([&listener]);
    drain.once();
    assert!(!drain.warm_up_to_pass_on(), "a message's notification is not a warm-up");
    assert_eq!(sub.receive().unwrap().unwrap().header.seq, 1);

    // a warm-up drained in a look that took a message: the message wakes the next stage
    out.warm_up().unwrap();
    out.send(|m: &mut ScanMsg| m.header = Header::new(2, monotonic_ns())).unwrap();
    let mut drain = ListenerDrain::new([&listener]);
    assert_eq!(sub.receive().unwrap().unwrap().header.seq, 2);
    drain.took_message();
    assert!(!drain.warm_up_to_pass_on(), "passed on a warm-up that came with a message");
}

/// A look makes two passes, takes a message with the time it took it, counts a scan no wake-up
/// announced once per look, and passes on a warm-up only when it took no message.
#[test]
fn a_look_passes_twice_and_counts_a_polled_scan_once() {
    use iceoryx2::prelude::BackpressureStrategy;
    let ScanReader { prefix, node, sub, listener, .. } = scan_reader("look");
    let mut out = Outlet::<ScanMsg>::open(&node, &prefix, Topic::Scan, BackpressureStrategy::DiscardData).unwrap();
    for seq in [1, 2] {
        out.send(|m: &mut ScanMsg| m.header = Header::new(seq, monotonic_ns())).unwrap();
    }

    let before = monotonic_ns();
    let mut look = Look::new([&listener], false);
    let (mut taken, mut passes, mut polled) = (Vec::new(), 0, 0);
    while look.next_pass() {
        passes += 1;
        while let Some((sample, at)) = look.receive(&sub).unwrap() {
            assert!(at >= before, "a message stamped before it was taken");
            taken.push(sample.header.seq);
            polled += u32::from(look.found_by_poll());
        }
    }
    assert_eq!((passes, taken, polled), (2, vec![1, 2], 1));
    assert!(!look.next_pass(), "a third pass");

    // woken by the scans: nothing is found by the poll
    out.send(|m: &mut ScanMsg| m.header = Header::new(3, monotonic_ns())).unwrap();
    let mut look = Look::new([&listener], true);
    assert!(look.next_pass());
    assert_eq!(look.receive(&sub).unwrap().map(|(s, _)| s.header.seq), Some(3));
    assert!(!look.found_by_poll());

    // a warm-up alone is passed on; the drain before the second pass found it
    out.warm_up().unwrap();
    let mut look = Look::new([&listener], false);
    while look.next_pass() {
        assert!(look.receive(&sub).unwrap().is_none());
    }
    assert!(look.warm_up_to_pass_on());
}

/// A service made by a process of another wire version is refused when opened, naming the
/// service and saying why, before any message is misread.
#[test]
fn a_service_of_another_wire_version_is_refused_at_connect_time() {
    use iceoryx2::prelude::*;
    let prefix = prefix("wire");
    let node = create_node("test").unwrap();
    let name = service_name(&prefix, "pose");
    let key = "gema2.wire_version".try_into().unwrap();
    let older = (WIRE_VERSION - 1).to_string();
    let attrs = AttributeSpecifier::new().define(&key, &older.as_str().try_into().unwrap()).unwrap();
    let _theirs = node
        .service_builder(&name.as_str().try_into().unwrap())
        .publish_subscribe::<PoseMsg>()
        .create_with_attributes(&attrs)
        .unwrap();
    let err = open_topic::<PoseMsg>(&node, &prefix, Topic::Pose).err().expect("refused").to_string();
    assert!(err.contains(&name) && err.contains("another wire version"), "{err}");
}
