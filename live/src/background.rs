//! The live view runs behind the recording, and catches up once it is done.
//!
//! While a recording runs, the live view's threads (the publisher and the
//! one thread driving the Foxglove server's tokio runtime) run at the lowest
//! normal scheduling priority, nice 19. On an idle core this changes
//! nothing: a live run at real time leaves the cores mostly idle and the
//! viewer gets every message as it is written. When the cores are busy (a
//! simulated `collect` as fast as it can go, or other work on the machine)
//! the scheduler gives the recording almost all of the time (weights 1024
//! against 15: about 1.5 % to the viewer); the live queue then fills and
//! drops messages for the viewer, and the recording never waits for it (see
//! [`slidetrack_session::LiveTap`]).
//!
//! A thread cannot raise its priority again without privileges, so the end
//! is handed over instead: at shutdown the background thread lets go of the
//! runtime ([`BackgroundRuntime::hand_over`]) and the caller, at its own
//! priority, drives the server's last messages and its stop.

use std::future::Future;
use std::sync::Arc;
use std::thread::JoinHandle;

use thread_priority::{ThreadPriority, set_current_thread_priority};
use tokio::runtime::Runtime;
use tokio::sync::oneshot;

use super::error::LiveError;

/// Lowers the calling thread to the lowest normal priority (nice 19). A
/// failure (a platform without niceness per thread) is logged and ignored:
/// the live view then competes with the recording as any thread does.
pub(crate) fn run_behind_the_recording() {
    if let Err(e) = set_current_thread_priority(ThreadPriority::Min) {
        tracing::debug!("live: cannot lower the priority of this thread: {e:?}");
    }
}

/// A single-threaded tokio runtime driven by a background thread at nice 19
/// until [`BackgroundRuntime::hand_over`], then by the caller.
pub(crate) struct BackgroundRuntime {
    /// Shared with the background thread: only `Runtime::block_on` drives a
    /// current-thread runtime's I/O and timers.
    runtime: Arc<Runtime>,
    /// Tells the background thread to let go of the runtime.
    release: Option<oneshot::Sender<()>>,
    driver: Option<JoinHandle<()>>,
}

impl BackgroundRuntime {
    /// A runtime not yet driven by anyone: start what it serves with
    /// [`BackgroundRuntime::block_on`], then [`BackgroundRuntime::drive_in_background`].
    pub(crate) fn new() -> Result<BackgroundRuntime, LiveError> {
        let runtime =
            tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(LiveError::Thread)?;
        Ok(BackgroundRuntime { runtime: Arc::new(runtime), release: None, driver: None })
    }

    /// Runs `future` to completion on the calling thread, which drives the
    /// runtime's tasks meanwhile. Not while the background thread drives it.
    pub(crate) fn block_on<F: Future>(&self, future: F) -> F::Output {
        debug_assert!(self.driver.is_none(), "the background thread drives the runtime");
        self.runtime.block_on(future)
    }

    /// Starts the background thread (nice 19) that drives the runtime's
    /// tasks until [`BackgroundRuntime::hand_over`].
    pub(crate) fn drive_in_background(&mut self) -> Result<(), LiveError> {
        let (release, released) = oneshot::channel::<()>();
        let runtime = Arc::clone(&self.runtime);
        let driver = std::thread::Builder::new()
            .name("live-io".into())
            .spawn(move || {
                run_behind_the_recording();
                runtime.block_on(async {
                    let _ = released.await;
                });
            })
            .map_err(LiveError::Thread)?;
        self.release = Some(release);
        self.driver = Some(driver);
        Ok(())
    }

    /// Stops the background thread; from here the caller drives the runtime
    /// with [`BackgroundRuntime::block_on`], at its own priority.
    pub(crate) fn hand_over(&mut self) {
        if let Some(release) = self.release.take() {
            let _ = release.send(());
        }
        if let Some(driver) = self.driver.take() {
            let _ = driver.join();
        }
    }

    /// A handle for the server to spawn its tasks on.
    pub(crate) fn handle(&self) -> &tokio::runtime::Handle {
        self.runtime.handle()
    }
}

impl Drop for BackgroundRuntime {
    fn drop(&mut self) {
        self.hand_over();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The niceness of the calling thread (Linux keeps one per thread).
    fn niceness() -> i32 {
        let status = std::fs::read_to_string("/proc/thread-self/stat").expect("stat");
        // Fields after the `)` closing the name; the nice value is field 19.
        let after_name = status.rsplit_once(')').expect("name").1;
        after_name.split_whitespace().nth(16).expect("nice field").parse().expect("number")
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn tasks_run_at_nice_19_in_the_background_and_at_the_callers_priority_after_the_hand_over() {
        let caller = niceness();
        let mut runtime = BackgroundRuntime::new().expect("runtime");
        runtime.drive_in_background().expect("background thread");
        let (tx, rx) = std::sync::mpsc::channel();
        runtime.handle().spawn(async move { tx.send(niceness()).expect("send") });
        let background =
            rx.recv_timeout(std::time::Duration::from_secs(10)).expect("the background thread ran the task");
        runtime.hand_over();
        let after = runtime.block_on(async { tokio::spawn(async { niceness() }).await.expect("join") });
        assert_eq!((background, after), (19, caller));
        assert_eq!(niceness(), caller, "the caller's own priority is left alone");
    }
}
