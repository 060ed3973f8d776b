//! The LCM instance: creation, publishing, subscriptions and dispatch.

use std::cell::{Cell, UnsafeCell};
use std::collections::HashMap;
use std::ffi::{c_char, c_void, CStr, CString};
use std::marker::PhantomData;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, RawFd};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr::NonNull;
use std::sync::atomic::{
    AtomicBool, AtomicU64, Ordering::Acquire, Ordering::Relaxed, Ordering::Release,
};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use crate::codec::Message;
use crate::error::{Error, Result};
use crate::sequence::SequenceTracker;

/// liblcm's default URL, used when neither a URL nor `LCM_DEFAULT_URL` is given.
pub const DEFAULT_URL: &str = "udpm://239.255.76.67:7667?ttl=0";

/// Longest channel name liblcm accepts, in bytes.
pub const MAX_CHANNEL_LEN: usize = lcm_sys::LCM_MAX_CHANNEL_NAME_LENGTH as usize;

const MAX_MESSAGE_SIZE: usize = lcm_sys::LCM_MAX_MESSAGE_SIZE as usize;

/// The URL an empty URL stands for: `$LCM_DEFAULT_URL` if set and not empty, else [`DEFAULT_URL`].
pub fn default_url() -> String {
    match std::env::var("LCM_DEFAULT_URL") {
        Ok(u) if !u.is_empty() => u,
        _ => DEFAULT_URL.to_owned(),
    }
}

/// Adds one to a counter that only one thread writes at a time (the handling thread, or a
/// publisher holding the publish lock): a plain load and store, no locked instruction.
#[inline]
fn bump(counter: &AtomicU64) {
    counter.store(counter.load(Relaxed) + 1, Relaxed);
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Counters for a whole instance (all subscriptions and publishers).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Stats {
    /// Messages published successfully.
    pub published: u64,
    /// Publishes liblcm refused.
    pub publish_errors: u64,
    /// Messages delivered to a callback.
    pub received: u64,
    /// Messages on typed subscriptions that did not decode (dropped, callback not called).
    pub decode_errors: u64,
    /// Callbacks that panicked (caught; the loop went on).
    pub handler_panics: u64,
    /// Messages missing from a publisher's sequence on typed subscriptions, summed over them
    /// (see [`SubscriptionStats::lost`]).
    pub lost: u64,
    /// Sequence streams started on typed subscriptions, summed over them (see
    /// [`SubscriptionStats::sequence_streams`]).
    pub sequence_streams: u64,
}

#[derive(Default)]
struct Counters {
    published: AtomicU64,
    publish_errors: AtomicU64,
    received: AtomicU64,
    decode_errors: AtomicU64,
    handler_panics: AtomicU64,
    lost: AtomicU64,
    sequence_streams: AtomicU64,
}

impl Counters {
    fn snapshot(&self) -> Stats {
        Stats {
            published: self.published.load(Relaxed),
            publish_errors: self.publish_errors.load(Relaxed),
            received: self.received.load(Relaxed),
            decode_errors: self.decode_errors.load(Relaxed),
            handler_panics: self.handler_panics.load(Relaxed),
            lost: self.lost.load(Relaxed),
            sequence_streams: self.sequence_streams.load(Relaxed),
        }
    }
}

/// The liblcm instance, shared by the [`Lcm`] and its [`Publisher`]s; destroyed with the last.
struct Shared {
    ptr: NonNull<lcm_sys::lcm_t>,
    url: String,
    /// Serialises publishes and holds the reusable encode buffer.
    publish: Mutex<Vec<u8>>,
    counters: Counters,
}

// SAFETY: liblcm's functions are internally synchronised; publishing is serialised by
// `publish`; handling only happens through `Lcm`, which is not `Sync`.
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Drop for Shared {
    fn drop(&mut self) {
        // SAFETY: the pointer came from lcm_create and this is the last owner.
        unsafe { lcm_sys::lcm_destroy(self.ptr.as_ptr()) }
    }
}

/// A thread-safe, cloneable handle that publishes on an LCM instance.
#[derive(Clone)]
pub struct Publisher {
    shared: Arc<Shared>,
    /// The instance's local bus and the channels that go there (see [`Lcm::with_local`]).
    local: Option<Arc<LocalRoute>>,
}

/// A second bus beside an instance's own, and the channels routed to it.
struct LocalRoute {
    channels: regex::RegexSet,
    patterns: Vec<String>,
    publisher: Publisher,
}

impl LocalRoute {
    fn takes(&self, channel: &str) -> bool {
        self.channels.is_match(channel)
    }
}

impl Stats {
    fn plus(self, o: Stats) -> Stats {
        Stats {
            published: self.published + o.published,
            publish_errors: self.publish_errors + o.publish_errors,
            received: self.received + o.received,
            decode_errors: self.decode_errors + o.decode_errors,
            handler_panics: self.handler_panics + o.handler_panics,
            lost: self.lost + o.lost,
            sequence_streams: self.sequence_streams + o.sequence_streams,
        }
    }
}

impl std::fmt::Debug for Publisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Publisher")
            .field("url", &self.shared.url)
            .finish()
    }
}

/// Copies a channel name into a NUL-terminated stack buffer, checking it.
fn channel_cstr(channel: &str, buf: &mut [u8; MAX_CHANNEL_LEN + 1]) -> Result<()> {
    let bad = |reason| Error::Channel {
        channel: channel.to_owned(),
        reason,
    };
    let b = channel.as_bytes();
    if b.is_empty() {
        return Err(bad("empty"));
    }
    if b.len() > MAX_CHANNEL_LEN {
        return Err(bad("longer than 63 bytes"));
    }
    let mut nul = false;
    for (d, &c) in buf.iter_mut().zip(b) {
        nul |= c == 0;
        *d = c;
    }
    if nul {
        return Err(bad("contains a NUL byte"));
    }
    buf[b.len()] = 0;
    Ok(())
}

impl Publisher {
    /// The URL of the instance.
    pub fn url(&self) -> &str {
        &self.shared.url
    }

    /// Publishes raw bytes on `channel`.
    pub fn publish_raw(&self, channel: &str, data: &[u8]) -> Result<()> {
        if let Some(local) = self.local.as_deref().filter(|l| l.takes(channel)) {
            return local.publisher.publish_raw(channel, data);
        }
        let _guard = lock(&self.shared.publish);
        self.publish_locked(channel, data)
    }

    fn publish_locked(&self, channel: &str, data: &[u8]) -> Result<()> {
        let mut name = [0u8; MAX_CHANNEL_LEN + 1];
        channel_cstr(channel, &mut name)?;
        if data.len() > MAX_MESSAGE_SIZE {
            return Err(Error::TooLarge {
                channel: channel.to_owned(),
                len: data.len(),
                max: MAX_MESSAGE_SIZE,
            });
        }
        // SAFETY: name is NUL-terminated, data is valid for data.len() bytes, and liblcm copies
        // both before returning.
        let rc = unsafe {
            lcm_sys::lcm_publish(
                self.shared.ptr.as_ptr(),
                name.as_ptr().cast(),
                data.as_ptr().cast(),
                data.len() as u32,
            )
        };
        // Both counters are only written under the publish lock.
        if rc == 0 {
            bump(&self.shared.counters.published);
            Ok(())
        } else {
            bump(&self.shared.counters.publish_errors);
            Err(Error::Publish {
                channel: channel.to_owned(),
                len: data.len(),
            })
        }
    }

    /// Encodes `msg` and publishes it on `channel`.
    pub fn publish<M: Message>(&self, channel: &str, msg: &M) -> Result<()> {
        if let Some(local) = self.local.as_deref().filter(|l| l.takes(channel)) {
            return local.publisher.publish(channel, msg);
        }
        let mut buf = lock(&self.shared.publish);
        buf.clear();
        msg.encode_into(&mut buf).map_err(|source| Error::Encode {
            channel: channel.to_owned(),
            source,
        })?;
        let result = self.publish_locked(channel, &buf);
        if buf.capacity() > 1 << 20 {
            // Do not keep a huge buffer alive after one large message.
            *buf = Vec::new();
        }
        result
    }

    /// Counters of the instance (its local bus's included).
    pub fn stats(&self) -> Stats {
        let own = self.shared.counters.snapshot();
        match &self.local {
            Some(l) => own.plus(l.publisher.stats()),
            None => own,
        }
    }
}

/// What a callback learns about a received message besides its bytes.
#[derive(Debug, Clone, Copy)]
pub struct RecvInfo<'a> {
    /// The channel it arrived on.
    pub channel: &'a str,
    /// Receive time, µs since the Unix epoch (kernel timestamp where available).
    pub recv_utime: i64,
    /// Size of the encoded message in bytes.
    pub size: usize,
}

/// Counters of one subscription.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct SubscriptionStats {
    /// Messages delivered to the callback.
    pub received: u64,
    /// Messages that did not decode (typed subscriptions).
    pub decode_errors: u64,
    /// Callback panics caught.
    pub handler_panics: u64,
    /// Messages lost before they reached this subscription (queue overflow, kernel drops, lost
    /// fragments), told by the gaps in their publishers' sequence numbers; typed subscriptions
    /// of types with a sequence number only.
    ///
    /// Per channel, each arriving number is matched to the publisher whose last number it
    /// follows most closely, by at most [`SequenceTracker::MAX_GAP`]` + 1`; the numbers it
    /// skipped count here. A number that follows none (another publisher, a restart, a log
    /// replay, a duplicate, a late message, a longer jump) counts as a new stream in
    /// [`sequence_streams`](Self::sequence_streams) and nothing lost. [`SequenceTracker`] has
    /// the details.
    pub lost: u64,
    /// Sequence streams started: one per channel for its first numbered message, plus one for
    /// every number that followed no stream (see [`lost`](Self::lost)). More than one per
    /// channel means several publishers, a restart or a replay, or a jump too long to count.
    pub sequence_streams: u64,
}

#[derive(Default)]
struct SubCounters {
    alive: AtomicBool,
    received: AtomicU64,
    decode_errors: AtomicU64,
    handler_panics: AtomicU64,
    lost: AtomicU64,
    sequence_streams: AtomicU64,
}

type RawHandler = Box<dyn FnMut(&RecvInfo<'_>, &[u8]) -> Outcome + Send>;

/// What a callback wrapper reports back to the trampoline.
enum Outcome {
    Delivered,
    DecodeError,
}

/// The user data liblcm hands back to the trampoline. Boxed, so its address is stable.
struct SubState {
    pattern: String,
    counters: Arc<SubCounters>,
    shared: Arc<Shared>,
    /// Only touched by the trampoline, which only runs on the thread inside `Lcm::handle*`.
    handler: UnsafeCell<RawHandler>,
    /// The last channel name seen, already checked as UTF-8 (same thread rule as `handler`).
    last_channel: UnsafeCell<String>,
}

struct Registered {
    raw: *mut lcm_sys::lcm_subscription_t,
    state: Box<SubState>,
}

/// Subscriptions of one instance. A dropped [`Subscription`] is only marked here; the thread
/// that handles unsubscribes it from liblcm between two dispatches, because liblcm does not
/// allow unsubscribing from inside a handler or while another thread dispatches.
struct Registry {
    shared: Arc<Shared>,
    subs: HashMap<u64, Registered>,
    next_id: u64,
    deferred: Vec<u64>,
    closed: bool,
}

// SAFETY: the raw subscription pointers are only used under the registry's mutex, and liblcm's
// subscription calls are internally synchronised.
unsafe impl Send for Registry {}

impl Registry {
    fn unsubscribe_now(&mut self, id: u64) {
        if let Some(reg) = self.subs.remove(&id) {
            // SAFETY: raw came from lcm_subscribe on this instance and is unsubscribed once.
            unsafe { lcm_sys::lcm_unsubscribe(self.shared.ptr.as_ptr(), reg.raw) };
            drop(reg.state);
        }
    }

    fn flush_deferred(&mut self) {
        for id in std::mem::take(&mut self.deferred) {
            self.unsubscribe_now(id);
        }
    }
}

/// A subscription; dropping it unsubscribes.
///
/// It may be dropped on any thread, even inside its own callback. The callback is never called
/// after the drop returns; liblcm forgets the subscription at the next `handle*` call (or when
/// the [`Lcm`] is dropped).
pub struct Subscription {
    id: u64,
    pattern: String,
    raw: *mut lcm_sys::lcm_subscription_t,
    counters: Arc<SubCounters>,
    registry: Arc<Mutex<Registry>>,
    pending: Arc<AtomicBool>,
}

// SAFETY: `raw` is only dereferenced by liblcm under the registry lock.
unsafe impl Send for Subscription {}
unsafe impl Sync for Subscription {}

impl std::fmt::Debug for Subscription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscription")
            .field("pattern", &self.pattern)
            .field("stats", &self.stats())
            .finish()
    }
}

impl Subscription {
    /// The channel pattern this subscription was made with.
    pub fn pattern(&self) -> &str {
        &self.pattern
    }

    /// Counters of this subscription.
    pub fn stats(&self) -> SubscriptionStats {
        let c = &self.counters;
        SubscriptionStats {
            received: c.received.load(Relaxed),
            decode_errors: c.decode_errors.load(Relaxed),
            handler_panics: c.handler_panics.load(Relaxed),
            lost: c.lost.load(Relaxed),
            sequence_streams: c.sequence_streams.load(Relaxed),
        }
    }

    /// Sets how many received messages liblcm queues for this subscription before it drops the
    /// oldest (liblcm's default is 30; 0 means unlimited).
    pub fn set_queue_capacity(&self, capacity: usize) -> Result<()> {
        let reg = lock(&self.registry);
        if reg.closed {
            return Ok(());
        }
        let n = i32::try_from(capacity).unwrap_or(i32::MAX);
        // SAFETY: raw is live: it is only unsubscribed after `alive` is cleared, which happens
        // in this subscription's drop or when the registry closes (checked above).
        unsafe { lcm_sys::lcm_subscription_set_queue_capacity(self.raw, n) };
        Ok(())
    }

    /// Messages liblcm currently queues for this subscription (udpm and other network
    /// providers; `memq://` keeps its own queue and reports 0); `None` with liblcm older than 1.4.
    pub fn queue_size(&self) -> Option<usize> {
        let reg = lock(&self.registry);
        if reg.closed {
            return Some(0);
        }
        // SAFETY: as in set_queue_capacity.
        let n = unsafe { lcm_sys::subscription_queue_size(self.raw) }?;
        usize::try_from(n).ok()
    }
}

impl Drop for Subscription {
    fn drop(&mut self) {
        // From here on the trampoline skips this subscription's callback.
        self.counters.alive.store(false, Relaxed);
        let mut reg = lock(&self.registry);
        if reg.closed {
            return;
        }
        reg.deferred.push(self.id);
        self.pending.store(true, Release);
    }
}

/// One LCM instance.
///
/// `Send` but not `Sync`: handling must stay on one thread at a time (a liblcm rule), so the
/// instance can be moved to the thread that runs the loop but not shared. Use
/// [`Lcm::publisher`] to publish from other threads.
///
/// ```compile_fail
/// fn needs_sync<T: Sync>() {}
/// needs_sync::<lcm::Lcm>();
/// ```
pub struct Lcm {
    publisher: Publisher,
    registry: Arc<Mutex<Registry>>,
    /// Set when a dropped subscription waits to be unsubscribed.
    pending: Arc<AtomicBool>,
    /// The local bus (see [`Lcm::with_local`]).
    local: Option<Box<Lcm>>,
    _not_sync: PhantomData<Cell<()>>,
}

impl std::fmt::Debug for Lcm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lcm")
            .field("url", &self.url())
            .field("stats", &self.stats())
            .finish()
    }
}

impl Lcm {
    /// Creates an instance for `url`; an empty URL means [`default_url`].
    ///
    /// Supported providers are those of the linked liblcm: `udpm://ADDR:PORT?ttl=N&recv_buf_size=N`,
    /// `mpudpm://…`, `memq://`, `file://PATH?mode=r|w|a&speed=S`, `tcpq://HOST:PORT`.
    ///
    /// A `tcpq://` server that cannot be reached is an [`Error::Connect`] (an older liblcm, such
    /// as Debian's 1.3, creates an instance without a descriptor, which aborts the process when
    /// waited on).
    pub fn new(url: &str) -> Result<Lcm> {
        let url = if url.is_empty() {
            default_url()
        } else {
            url.to_owned()
        };
        let curl = CString::new(url.as_str()).map_err(|_| Error::Create { url: url.clone() })?;
        // liblcm's tcpq provider fails (1.5.3) or stays without a socket (1.3) when it cannot
        // connect; both are one error here. Other providers are not asked for their
        // descriptor: udpm's lcm_get_fileno would set up receiving, with its self-test.
        let tcpq = url
            .split_once("://")
            .is_some_and(|(scheme, _)| scheme == "tcpq");
        let failed = || {
            let url = url.clone();
            if tcpq {
                Error::Connect { url }
            } else {
                Error::Create { url }
            }
        };
        // SAFETY: curl is a valid C string; lcm_create returns NULL on failure.
        let ptr = unsafe { lcm_sys::lcm_create(curl.as_ptr()) };
        let ptr = NonNull::new(ptr).ok_or_else(failed)?;
        // SAFETY: the pointer came from lcm_create and is live.
        if tcpq && unsafe { lcm_sys::lcm_get_fileno(ptr.as_ptr()) } < 0 {
            // SAFETY: nothing else holds the pointer; it is not used again.
            unsafe { lcm_sys::lcm_destroy(ptr.as_ptr()) };
            return Err(failed());
        }
        let shared = Arc::new(Shared {
            ptr,
            url,
            publish: Mutex::new(Vec::new()),
            counters: Counters::default(),
        });
        let registry = Arc::new(Mutex::new(Registry {
            shared: shared.clone(),
            subs: HashMap::new(),
            next_id: 0,
            deferred: Vec::new(),
            closed: false,
        }));
        Ok(Lcm {
            publisher: Publisher {
                shared,
                local: None,
            },
            registry,
            pending: Arc::new(AtomicBool::new(false)),
            local: None,
            _not_sync: PhantomData,
        })
    }

    /// An instance on `url` with a second, local bus on `local_url` for the channels that match
    /// one of `local_channels` (regular expressions anchored at both ends, as subscriptions'):
    /// a robot's full-rate data (joint states, set-points, CAN frames) stays on a bus of its
    /// own computer (`ttl=0`, its own port) while the rest is shared with the other hosts.
    ///
    /// A publish goes to the bus its channel is routed to; a subscription goes to the bus its
    /// pattern, read as a channel name, is routed to (subscribe to the local channels by name
    /// or by a pattern that the local patterns match). [`Lcm::handle`] and
    /// [`Lcm::handle_timeout`] wait on both buses; [`Lcm::fileno`] is the shared bus's only.
    /// With no local channels this is [`Lcm::new`].
    pub fn with_local(url: &str, local_url: &str, local_channels: &[String]) -> Result<Lcm> {
        let mut lcm = Lcm::new(url)?;
        if local_channels.is_empty() {
            return Ok(lcm);
        }
        let anchored: Vec<String> = local_channels
            .iter()
            .map(|p| format!("^(?:{p})$"))
            .collect();
        let channels = regex::RegexSet::new(&anchored).map_err(|e| {
            let pattern = local_channels
                .iter()
                .find(|p| regex::Regex::new(p).is_err())
                .cloned()
                .unwrap_or_default();
            Error::Route {
                pattern,
                reason: e.to_string().lines().last().unwrap_or("").trim().to_owned(),
            }
        })?;
        let local = Lcm::new(local_url)?;
        lcm.publisher.local = Some(Arc::new(LocalRoute {
            channels,
            patterns: local_channels.to_vec(),
            publisher: local.publisher(),
        }));
        lcm.local = Some(Box::new(local));
        Ok(lcm)
    }

    /// The URL of this instance (the shared bus's, with a local bus).
    pub fn url(&self) -> &str {
        self.publisher.url()
    }

    /// The local bus's URL and the channel patterns routed to it, if the instance has one.
    pub fn local_bus(&self) -> Option<(&str, &[String])> {
        let route = self.publisher.local.as_deref()?;
        Some((route.publisher.url(), &route.patterns))
    }

    /// The instance a subscription to `pattern` belongs on.
    fn bus_for(&self, pattern: &str) -> &Lcm {
        match (&self.local, &self.publisher.local) {
            (Some(lcm), Some(route)) if route.takes(pattern) => lcm,
            _ => self,
        }
    }

    /// A handle that publishes on this instance from any thread.
    pub fn publisher(&self) -> Publisher {
        self.publisher.clone()
    }

    /// Counters of the instance (its local bus's included).
    pub fn stats(&self) -> Stats {
        self.publisher.stats()
    }

    /// Publishes raw bytes.
    pub fn publish_raw(&self, channel: &str, data: &[u8]) -> Result<()> {
        self.publisher.publish_raw(channel, data)
    }

    /// Encodes and publishes a typed message.
    pub fn publish<M: Message>(&self, channel: &str, msg: &M) -> Result<()> {
        self.publisher.publish(channel, msg)
    }

    fn subscribe_handler(
        &self,
        pattern: &str,
        counters: Arc<SubCounters>,
        handler: RawHandler,
    ) -> Result<Subscription> {
        let err = || Error::Subscribe {
            pattern: pattern.to_owned(),
        };
        let cpattern = CString::new(pattern).map_err(|_| err())?;
        counters.alive.store(true, Relaxed);
        let state = Box::new(SubState {
            pattern: pattern.to_owned(),
            counters: counters.clone(),
            shared: self.publisher.shared.clone(),
            handler: UnsafeCell::new(handler),
            last_channel: UnsafeCell::new(String::new()),
        });
        let mut reg = lock(&self.registry);
        let user = (&*state as *const SubState).cast_mut().cast::<c_void>();
        // SAFETY: the pattern is a valid C string; `user` points into a Box that lives in the
        // registry until lcm_unsubscribe has been called for this subscription.
        let raw = unsafe {
            lcm_sys::lcm_subscribe(
                self.publisher.shared.ptr.as_ptr(),
                cpattern.as_ptr(),
                Some(trampoline),
                user,
            )
        };
        if raw.is_null() {
            return Err(err());
        }
        let id = reg.next_id;
        reg.next_id += 1;
        reg.subs.insert(id, Registered { raw, state });
        Ok(Subscription {
            id,
            pattern: pattern.to_owned(),
            raw,
            counters,
            registry: self.registry.clone(),
            pending: self.pending.clone(),
        })
    }

    /// Subscribes `handler` to the raw bytes of every channel matching `pattern`.
    ///
    /// `pattern` is a regular expression, anchored at both ends (`POSE`, `CAN_.*`, `.*`).
    pub fn subscribe_raw<F>(&self, pattern: &str, mut handler: F) -> Result<Subscription>
    where
        F: FnMut(&RecvInfo<'_>, &[u8]) + Send + 'static,
    {
        let bus = self.bus_for(pattern);
        if !std::ptr::eq(bus, self) {
            return bus.subscribe_raw(pattern, handler);
        }
        self.subscribe_handler(
            pattern,
            Arc::default(),
            Box::new(move |info, data| {
                handler(info, data);
                Outcome::Delivered
            }),
        )
    }

    /// Subscribes `handler` to decoded messages of type `M` on channels matching `pattern`.
    ///
    /// Messages that do not decode (wrong fingerprint, malformed) are counted, logged, and not
    /// passed to the handler. For types carrying a sequence number, gaps are counted as lost
    /// per channel and publisher, as [`SubscriptionStats::lost`] describes.
    pub fn subscribe<M, F>(&self, pattern: &str, mut handler: F) -> Result<Subscription>
    where
        M: Message + 'static,
        F: FnMut(&RecvInfo<'_>, M) + Send + 'static,
    {
        let bus = self.bus_for(pattern);
        if !std::ptr::eq(bus, self) {
            return bus.subscribe(pattern, handler);
        }
        let mut trackers: HashMap<String, SequenceTracker> = HashMap::new();
        let counters = Arc::new(SubCounters::default());
        let sub_counters = counters.clone();
        let shared = self.publisher.shared.clone();
        self.subscribe_handler(
            pattern,
            counters,
            Box::new(move |info, data| match M::decode(data) {
                Ok(msg) => {
                    if let Some(seq) = msg.sequence() {
                        let tracker = match trackers.get_mut(info.channel) {
                            Some(t) => t,
                            None => trackers.entry(info.channel.to_owned()).or_default(),
                        };
                        let streams = tracker.streams();
                        let gap = tracker.observe(seq);
                        if gap > 0 {
                            sub_counters.lost.fetch_add(gap, Relaxed);
                            shared.counters.lost.fetch_add(gap, Relaxed);
                            tracing::debug!(channel = info.channel, gap, "messages lost");
                        } else if tracker.streams() != streams {
                            sub_counters.sequence_streams.fetch_add(1, Relaxed);
                            shared.counters.sequence_streams.fetch_add(1, Relaxed);
                            if streams > 0 {
                                tracing::debug!(
                                    channel = info.channel,
                                    sequence = seq,
                                    "a new sequence stream: another publisher, a restart or a replay"
                                );
                            }
                        }
                    }
                    handler(info, msg);
                    Outcome::Delivered
                }
                Err(e) => {
                    // The first ten, then every power of two: a flood of garbage does not
                    // flood the log, and the counter keeps the exact number.
                    let n = sub_counters.decode_errors.load(Relaxed) + 1;
                    if n <= 10 || n.is_power_of_two() {
                        tracing::warn!(
                            channel = info.channel,
                            size = info.size,
                            r#type = M::TYPE_NAME,
                            error = %e,
                            count = n,
                            "dropping a message that does not decode"
                        );
                    }
                    Outcome::DecodeError
                }
            }),
        )
    }

    /// Unsubscribes the subscriptions dropped since the last call. Only the handling thread
    /// calls it, between dispatches.
    fn flush_dropped(&self) {
        if self.pending.load(Relaxed) && self.pending.swap(false, Acquire) {
            lock(&self.registry).flush_deferred();
        }
    }

    fn dispatch<T>(&self, f: impl FnOnce(*mut lcm_sys::lcm_t) -> T) -> T {
        self.flush_dropped();
        let out = f(self.publisher.shared.ptr.as_ptr());
        self.flush_dropped();
        out
    }

    /// Waits for one message and dispatches it to every matching subscription.
    ///
    /// A signal arriving while it waits (EINTR) returns `Ok` without dispatching, so a loop can
    /// check its shutdown flag.
    pub fn handle(&self) -> Result<()> {
        if let Some(local) = &self.local {
            return self.handle_both(local, None).map(|_| ());
        }
        // SAFETY: the pointer is live; `Lcm` is not Sync, so no other thread handles.
        let rc = self.dispatch(|p| unsafe { lcm_sys::lcm_handle(p) });
        if rc == 0 || interrupted() {
            Ok(())
        } else {
            Err(Error::Handle {
                url: self.url().to_owned(),
            })
        }
    }

    /// Waits up to `timeout` for one message and dispatches it; `Ok(false)` on timeout.
    /// Sub-millisecond timeouts are rounded up to 1 ms (liblcm's resolution); zero polls.
    ///
    /// [`Error::NoDescriptor`] when the instance has nothing to wait on (see [`Lcm::fileno`]).
    pub fn handle_timeout(&self, timeout: Duration) -> Result<bool> {
        match &self.local {
            Some(local) => self.handle_both(local, Some(timeout)),
            None => self.handle_own(timeout),
        }
    }

    /// Waits on this instance and its local bus together, then dispatches one message from
    /// each that has one. A bus without a subscription is not waited on: asking liblcm for its
    /// descriptor would make it receive (and wake for) all of that bus's traffic, for nothing.
    fn handle_both(&self, local: &Lcm, timeout: Option<Duration>) -> Result<bool> {
        let buses = [self, local];
        let mut polls = [libc::pollfd {
            fd: -1,
            events: libc::POLLIN,
            revents: 0,
        }; 2];
        for (p, bus) in polls.iter_mut().zip(buses) {
            if lock(&bus.registry).subs.is_empty() {
                continue;
            }
            p.fd = bus.fileno();
            if p.fd < 0 {
                return Err(Error::NoDescriptor {
                    url: bus.url().to_owned(),
                });
            }
        }
        let ms = timeout.map_or(-1, timeout_ms);
        // SAFETY: polls is a valid array of two pollfd.
        let rc = unsafe { libc::poll(polls.as_mut_ptr(), 2, ms) };
        if rc < 0 {
            return if interrupted() {
                Ok(false)
            } else {
                Err(Error::Handle {
                    url: self.url().to_owned(),
                })
            };
        }
        let mut any = false;
        for (p, bus) in polls.iter().zip(buses) {
            if p.revents != 0 {
                any |= bus.handle_own(Duration::ZERO)?;
            }
        }
        Ok(any)
    }

    fn handle_own(&self, timeout: Duration) -> Result<bool> {
        // liblcm would put the descriptor in an fd_set, and glibc aborts on -1.
        if self.fileno() < 0 {
            return Err(Error::NoDescriptor {
                url: self.url().to_owned(),
            });
        }
        let ms = timeout_ms(timeout);
        // SAFETY: as in `handle`.
        let rc = self.dispatch(|p| unsafe { lcm_sys::lcm_handle_timeout(p, ms) });
        match rc {
            n if n > 0 => Ok(true),
            0 => Ok(false),
            _ if interrupted() => Ok(false),
            _ => Err(Error::Handle {
                url: self.url().to_owned(),
            }),
        }
    }

    /// Dispatches every message already queued, without waiting; returns how many.
    pub fn handle_pending(&self) -> Result<usize> {
        let mut n = 0;
        while self.handle_timeout(Duration::ZERO)? {
            n += 1;
        }
        Ok(n)
    }

    /// The file descriptor that is readable while messages wait; for `poll`/`epoll` loops.
    /// When it is readable, [`Lcm::handle`] will not block.
    ///
    /// With a local bus ([`Lcm::with_local`]) this is the shared bus's descriptor only.
    ///
    /// -1 when the instance has none: a `tcpq://` instance whose server connection broke
    /// (liblcm reconnects in [`Lcm::handle`] and publishes, with a new descriptor), or a
    /// `udpm://` instance that could not set up receiving.
    pub fn fileno(&self) -> RawFd {
        // SAFETY: the pointer is live.
        unsafe { lcm_sys::lcm_get_fileno(self.publisher.shared.ptr.as_ptr()) }
    }

    /// The descriptor of [`Lcm::fileno`], borrowed; [`Error::NoDescriptor`] when there is none.
    ///
    /// On `tcpq://`, liblcm closes the descriptor when the connection breaks inside
    /// [`Lcm::handle`] or a publish: do not keep the borrow across those calls.
    pub fn try_fd(&self) -> Result<BorrowedFd<'_>> {
        match self.fileno() {
            fd if fd >= 0 => {
                // SAFETY: fd is open. liblcm closes it when the instance is destroyed, which this
                // borrow of `self` outlasts, or (tcpq:// only) when its connection breaks, which
                // the doc above tells callers to keep the borrow clear of.
                Ok(unsafe { BorrowedFd::borrow_raw(fd) })
            }
            _ => Err(Error::NoDescriptor {
                url: self.url().to_owned(),
            }),
        }
    }
}

impl AsRawFd for Lcm {
    /// [`Lcm::fileno`]: -1 when the instance has no descriptor.
    fn as_raw_fd(&self) -> RawFd {
        self.fileno()
    }
}

impl AsFd for Lcm {
    /// [`Lcm::try_fd`], for instances known to have a descriptor.
    ///
    /// # Panics
    /// When the instance has none (see [`Lcm::fileno`]).
    fn as_fd(&self) -> BorrowedFd<'_> {
        self.try_fd().unwrap_or_else(|e| panic!("{e}"))
    }
}

impl Drop for Lcm {
    fn drop(&mut self) {
        let mut reg = lock(&self.registry);
        let ids: Vec<u64> = reg.subs.keys().copied().collect();
        for id in ids {
            if let Some(r) = reg.subs.get(&id) {
                r.state.counters.alive.store(false, Relaxed);
            }
            reg.unsubscribe_now(id);
        }
        reg.deferred.clear();
        reg.closed = true;
    }
}

/// A timeout in liblcm's milliseconds: sub-millisecond ones rounded up, zero kept.
fn timeout_ms(timeout: Duration) -> i32 {
    let ms = timeout.as_millis().min(i32::MAX as u128) as i32;
    if ms == 0 && !timeout.is_zero() {
        1
    } else {
        ms
    }
}

/// True when the last failed system call was interrupted by a signal.
fn interrupted() -> bool {
    std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted
}

/// The C callback: finds the subscription, runs its handler behind `catch_unwind`.
unsafe extern "C" fn trampoline(
    rbuf: *const lcm_sys::lcm_recv_buf_t,
    channel: *const c_char,
    user: *mut c_void,
) {
    // SAFETY: `user` is the SubState registered with this subscription, alive until it is
    // unsubscribed, which never happens while a dispatch runs.
    let state = unsafe { &*(user as *const SubState) };
    if !state.counters.alive.load(Relaxed) {
        return;
    }
    // SAFETY: liblcm passes a valid buffer and NUL-terminated channel for the call's duration.
    let (rbuf, channel) = unsafe { (&*rbuf, CStr::from_ptr(channel)) };
    let data: &[u8] = if rbuf.data.is_null() || rbuf.data_size == 0 {
        &[]
    } else {
        // SAFETY: liblcm guarantees data_size readable bytes at data during the callback.
        unsafe { std::slice::from_raw_parts(rbuf.data as *const u8, rbuf.data_size as usize) }
    };
    // SAFETY: only the handling thread touches `last_channel` (see `handler` below).
    let last = unsafe { &mut *state.last_channel.get() };
    let bytes = channel.to_bytes();
    if last.as_bytes() != bytes {
        *last = String::from_utf8_lossy(bytes).into_owned();
    }
    let channel = last.as_str();
    let info = RecvInfo {
        channel,
        recv_utime: rbuf.recv_utime,
        size: data.len(),
    };
    // SAFETY: only this trampoline touches the handler, and it runs on the single thread that
    // is inside Lcm::handle*, never re-entrantly (liblcm refuses recursive handle calls).
    let handler = unsafe { &mut *state.handler.get() };
    let global = &state.shared.counters;
    // The dispatch counters are only written here, on the handling thread.
    match catch_unwind(AssertUnwindSafe(|| handler(&info, data))) {
        Ok(Outcome::Delivered) => {
            bump(&state.counters.received);
            bump(&global.received);
        }
        Ok(Outcome::DecodeError) => {
            bump(&state.counters.decode_errors);
            bump(&global.decode_errors);
        }
        Err(payload) => {
            bump(&state.counters.handler_panics);
            bump(&global.handler_panics);
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "non-string panic payload".into());
            tracing::error!(
                channel,
                subscription = state.pattern.as_str(),
                panic = what.as_str(),
                "a message handler panicked; the message was dropped and the loop goes on"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send<T: Send>() {}
    fn assert_sync<T: Sync>() {}

    #[test]
    fn thread_safety_of_the_types() {
        assert_send::<Lcm>();
        assert_send::<Publisher>();
        assert_sync::<Publisher>();
        assert_send::<Subscription>();
    }

    #[test]
    fn channel_names_are_checked() {
        let mut buf = [0u8; MAX_CHANNEL_LEN + 1];
        assert!(channel_cstr("POSE", &mut buf).is_ok());
        assert!(channel_cstr("", &mut buf).is_err());
        assert!(channel_cstr(&"x".repeat(64), &mut buf).is_err());
        assert!(channel_cstr(&"x".repeat(63), &mut buf).is_ok());
        assert!(channel_cstr("a\0b", &mut buf).is_err());
    }
}
