//! [`play`]: a recorded session served to Foxglove at its recorded timing,
//! with the play, pause, seek and speed controls of Foxglove's player.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use foxglove::websocket::{
    Capability, ChannelView, Client, PlaybackCommand, PlaybackControlRequest, PlaybackState, PlaybackStatus,
    ServerListener,
};
use foxglove::{
    ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer, WebSocketServerHandle,
};
use mcap::Summary;
use mcap::records::MessageHeader;
use mcap::sans_io::indexed_reader::{IndexedReadEvent, IndexedReader, IndexedReaderOptions};
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};

use super::address::resolve_addr;
use super::error::LiveError;
use super::front_door;
use super::player_clock::PlayClock;
use super::server::stop_server;

/// Slowest playback speed a viewer may ask for.
const MIN_SPEED: f64 = 0.01;
/// Longest sleep of the playback loop, so that controls act promptly.
const MAX_SLEEP: Duration = Duration::from_millis(20);
/// Time a viewer has to finish subscribing before playback starts.
const SUBSCRIBE_GRACE: Duration = Duration::from_millis(200);
/// Least log time between two time broadcasts (ns): 60 Hz.
const TIME_BROADCAST_NS: u64 = 1_000_000_000 / 60;

/// How to play a session.
#[derive(Clone, Debug, PartialEq)]
pub struct PlayOptions {
    /// Where to serve (`HOST:PORT`).
    pub addr: String,
    /// Log time per wall time: 1 plays at the recorded timing, 2 twice as fast.
    pub rate: f64,
    /// Start again from the beginning at the end, until stopped.
    pub looping: bool,
    /// Start playing only once a viewer has subscribed (else at once).
    pub wait_for_viewer: bool,
}

/// What a playback did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlayReport {
    /// Messages published.
    pub messages: u64,
    /// Times playback reached the end.
    pub endings: u64,
}

/// The session being played and where playback is.
struct Player {
    path: PathBuf,
    summary: Summary,
    file: BufReader<File>,
    reader: IndexedReader,
    chunk: Vec<u8>,
    channels: HashMap<u16, Arc<RawChannel>>,
    /// First and last log time (ns).
    range: (u64, u64),
    status: PlaybackStatus,
    speed: f64,
    /// Log time of the last message sent, or of the seek (ns).
    current_ns: u64,
    clock: Option<PlayClock>,
    pending: Option<(MessageHeader, Vec<u8>)>,
    last_broadcast_ns: Option<u64>,
    report: PlayReport,
}

/// What the playback loop does next.
enum Step {
    Sent,
    Wait(Duration),
    Ended,
}

fn lock(player: &Mutex<Player>) -> MutexGuard<'_, Player> {
    player.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Player {
    fn open(path: &Path, context: &Arc<Context>, speed: f64) -> Result<Player, LiveError> {
        let fail = |detail: String| LiveError::Session { path: path.to_path_buf(), detail };
        let mut file = BufReader::new(File::open(path).map_err(|e| fail(format!("cannot open it: {e}")))?);
        let summary = load_summary(&mut file)
            .map_err(fail)?
            .ok_or_else(|| fail("has no summary (cut short?); it cannot be played".into()))?;
        let range = match &summary.stats {
            Some(s) if s.message_count > 0 => (s.message_start_time, s.message_end_time),
            _ => return Err(fail("holds no messages".into())),
        };
        let mut channels = HashMap::new();
        for (&id, c) in &summary.channels {
            let schema =
                c.schema.as_ref().map(|s| Schema::new(s.name.as_str(), s.encoding.as_str(), s.data.to_vec()));
            let channel = ChannelBuilder::new(c.topic.as_str())
                .message_encoding(c.message_encoding.as_str())
                .schema(schema)
                .metadata(c.metadata.clone())
                .context(context)
                .build_raw()?;
            channels.insert(id, channel);
        }
        let reader = reader_from(&summary, range.0).map_err(fail)?;
        Ok(Player {
            path: path.to_path_buf(),
            summary,
            file,
            reader,
            chunk: Vec::new(),
            channels,
            range,
            status: PlaybackStatus::Paused,
            speed: speed.max(MIN_SPEED),
            current_ns: range.0,
            clock: None,
            pending: None,
            last_broadcast_ns: None,
            report: PlayReport::default(),
        })
    }

    fn seek(&mut self, t_ns: u64) -> Result<(), LiveError> {
        let t_ns = t_ns.clamp(self.range.0, self.range.1);
        self.reader = reader_from(&self.summary, t_ns).map_err(|detail| self.error(detail))?;
        self.current_ns = t_ns;
        self.pending = None;
        self.last_broadcast_ns = None;
        // The clock starts again at the next message; keep a pause.
        self.clock = None;
        if self.status == PlaybackStatus::Ended {
            self.status = PlaybackStatus::Paused;
        }
        Ok(())
    }

    fn play(&mut self) {
        if self.status != PlaybackStatus::Ended {
            self.status = PlaybackStatus::Playing;
            if let Some(c) = &mut self.clock {
                c.resume();
            }
        }
    }

    fn pause(&mut self) {
        if self.status != PlaybackStatus::Ended {
            self.status = PlaybackStatus::Paused;
            if let Some(c) = &mut self.clock {
                c.pause();
            }
        }
    }

    fn set_speed(&mut self, speed: f64) {
        let speed = if speed.is_finite() { speed.max(MIN_SPEED) } else { self.speed };
        self.speed = speed;
        if let Some(c) = &mut self.clock {
            c.set_speed(speed);
        }
    }

    fn state(&self, did_seek: bool, request_id: Option<String>) -> PlaybackState {
        PlaybackState {
            status: self.status,
            current_time: self.current_ns,
            playback_speed: self.speed as f32,
            did_seek,
            request_id,
        }
    }

    fn error(&self, detail: String) -> LiveError {
        LiveError::Session { path: self.path.clone(), detail }
    }

    /// Sends the next message if it is due.
    fn step(&mut self, server: &WebSocketServerHandle) -> Result<Step, LiveError> {
        if self.status != PlaybackStatus::Playing {
            return Ok(Step::Wait(MAX_SLEEP));
        }
        let next = match self.pending.take() {
            Some(m) => Some(m),
            None => self.next_message()?,
        };
        let Some((header, data)) = next else {
            self.status = PlaybackStatus::Ended;
            self.current_ns = self.range.1;
            self.report.endings += 1;
            return Ok(Step::Ended);
        };
        let speed = self.speed;
        let clock = self.clock.get_or_insert_with(|| PlayClock::start(header.log_time, speed));
        if let Some(wait) = clock.wait_for(header.log_time) {
            self.pending = Some((header, data));
            return Ok(Step::Wait(wait));
        }
        self.current_ns = header.log_time;
        if self.last_broadcast_ns.is_none_or(|t| header.log_time.saturating_sub(t) >= TIME_BROADCAST_NS) {
            server.broadcast_time(header.log_time);
            self.last_broadcast_ns = Some(header.log_time);
        }
        if let Some(channel) = self.channels.get(&header.channel_id) {
            channel.log_with_meta(&data, PartialMetadata { log_time: Some(header.log_time) });
            self.report.messages += 1;
        }
        Ok(Step::Sent)
    }

    fn next_message(&mut self) -> Result<Option<(MessageHeader, Vec<u8>)>, LiveError> {
        loop {
            let event = match self.reader.next_event() {
                None => return Ok(None),
                Some(Err(e)) => return Err(self.error(format!("cannot read it: {e}"))),
                Some(Ok(event)) => event,
            };
            match event {
                IndexedReadEvent::ReadChunkRequest { offset, length } => {
                    self.chunk.resize(length, 0);
                    let read = self
                        .file
                        .seek(SeekFrom::Start(offset))
                        .and_then(|_| self.file.read_exact(&mut self.chunk));
                    if let Err(e) = read {
                        return Err(LiveError::Session {
                            path: self.path.clone(),
                            detail: format!("cannot read it: {e}"),
                        });
                    }
                    if let Err(e) = self.reader.insert_chunk_record_data(offset, &self.chunk) {
                        return Err(LiveError::Session {
                            path: self.path.clone(),
                            detail: format!("corrupt chunk: {e}"),
                        });
                    }
                }
                IndexedReadEvent::Message { header, data } => return Ok(Some((header, data.to_vec()))),
            }
        }
    }
}

/// A reader of the messages at or after `start_ns`, in log-time order.
fn reader_from(summary: &Summary, start_ns: u64) -> Result<IndexedReader, String> {
    IndexedReader::new_with_options(summary, IndexedReaderOptions::new().starting_at(start_ns))
        .map_err(|e| format!("cannot index it: {e}"))
}

/// The summary section of an MCAP file, `None` when it has none.
fn load_summary<R: Read + Seek>(file: &mut R) -> Result<Option<Summary>, String> {
    let mut reader = SummaryReader::new();
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| format!("not a readable MCAP file ({e})"))? {
            SummaryReadEvent::ReadRequest(n) => {
                let read = file.read(reader.insert(n)).map_err(|e| format!("cannot read it: {e}"))?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(pos) => {
                let pos = file.seek(pos).map_err(|e| format!("cannot read it: {e}"))?;
                reader.notify_seeked(pos);
            }
        }
    }
    Ok(reader.finish())
}

/// Answers Foxglove's playback controls and notes the first subscription.
struct Controls {
    player: Arc<Mutex<Player>>,
    subscribed: AtomicBool,
}

impl ServerListener for Controls {
    fn on_subscribe(&self, _client: Client, _channel: ChannelView) {
        self.subscribed.store(true, Ordering::Release);
    }

    fn on_playback_control_request(&self, request: PlaybackControlRequest) -> Option<PlaybackState> {
        let mut player = lock(&self.player);
        let mut did_seek = false;
        if let Some(t) = request.seek_time {
            match player.seek(t) {
                Ok(()) => did_seek = true,
                Err(e) => tracing::warn!("cannot seek: {e}"),
            }
        }
        player.set_speed(f64::from(request.playback_speed));
        match request.playback_command {
            PlaybackCommand::Play => player.play(),
            PlaybackCommand::Pause => player.pause(),
        }
        // The SDK broadcasts the state it gets back.
        Some(player.state(did_seek, Some(request.request_id)))
    }
}

/// Serves `path` on `options.addr` until it has played to the end (and no
/// viewer is left), or until `stop`. `listening` gets the bound address
/// before anything is played. Messages go out with their log times, each
/// when its log time is due on a clock that starts at the first message and
/// runs `options.rate` times as fast as the wall clock.
pub fn play(
    path: &Path,
    options: &PlayOptions,
    stop: &AtomicBool,
    listening: &mut dyn FnMut(SocketAddr),
) -> Result<PlayReport, LiveError> {
    let requested = resolve_addr(&options.addr)?;
    let context = Context::new();
    let player = Arc::new(Mutex::new(Player::open(path, &context, options.rate)?));
    let range = lock(&player).range;
    let controls = Arc::new(Controls { player: Arc::clone(&player), subscribed: AtomicBool::new(false) });
    let name = path.file_name().map_or_else(|| "session".into(), |n| n.to_string_lossy().into_owned());
    // The server's runtime, with the front door (see `front_door.rs`) in front of it.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name("live-play")
        .enable_all()
        .build()
        .map_err(LiveError::Thread)?;
    let door = runtime
        .block_on(tokio::net::TcpListener::bind(requested))
        .map_err(|source| LiveError::Bind { addr: requested, source })?;
    let addr = door.local_addr().map_err(|source| LiveError::Bind { addr: requested, source })?;
    let starting = WebSocketServer::new()
        .name(name)
        .context(&context)
        .capabilities([Capability::PlaybackControl, Capability::Time])
        .playback_time_range(range.0, range.1)
        .listener(Arc::clone(&controls) as Arc<dyn ServerListener>)
        .tokio_runtime(runtime.handle())
        .bind(front_door::BACKEND_HOST, 0)
        .start();
    let server = runtime.block_on(starting).map_err(|e| LiveError::starting(requested, e))?;
    runtime.spawn(front_door::serve(door, front_door::backend_addr(server.port())));
    listening(addr);
    let result = run(&server, &player, &controls, options, stop);
    stop_server(server);
    runtime.shutdown_background();
    result
}

/// The playback loop.
fn run(
    server: &WebSocketServerHandle,
    player: &Mutex<Player>,
    controls: &Controls,
    options: &PlayOptions,
    stop: &AtomicBool,
) -> Result<PlayReport, LiveError> {
    let mut started = !options.wait_for_viewer;
    if started {
        lock(player).play();
    }
    while !stop.load(Ordering::Acquire) {
        if !started {
            if controls.subscribed.load(Ordering::Acquire) {
                std::thread::sleep(SUBSCRIBE_GRACE);
                let mut p = lock(player);
                p.play();
                server.broadcast_playback_state(p.state(false, None));
                started = true;
            } else {
                std::thread::sleep(MAX_SLEEP);
            }
            continue;
        }
        let step = lock(player).step(server)?;
        match step {
            Step::Sent => {}
            Step::Wait(wait) => std::thread::sleep(wait.min(MAX_SLEEP)),
            Step::Ended => {
                let mut p = lock(player);
                if options.looping {
                    let start = p.range.0;
                    p.seek(start)?;
                    p.play();
                    server.broadcast_playback_state(p.state(true, None));
                } else {
                    server.broadcast_playback_state(p.state(false, None));
                    drop(p);
                    // Viewers may still seek back; stay while one is connected.
                    while server.client_count() > 0 && !stop.load(Ordering::Acquire) {
                        std::thread::sleep(MAX_SLEEP);
                        if lock(player).status != PlaybackStatus::Ended {
                            break;
                        }
                    }
                    if lock(player).status == PlaybackStatus::Ended {
                        break;
                    }
                }
            }
        }
    }
    Ok(lock(player).report)
}
