//! Work too slow for an app's loop (a footstep search, an image's matching, a map's update) on
//! a job thread of its own: one job at a time, the newest waiting job wins, a job that panics
//! is answered with the panic's words and the thread goes on, a thread that has gone is
//! started again. Cancelling a running job is the job's own flag (the planners' `Cancel`):
//! the app keeps it and sets it.

use std::sync::mpsc;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A job's answer.
#[derive(Debug)]
pub struct Done<J, R> {
    /// The job.
    pub job: J,
    /// What it gave, or the words of its panic.
    pub out: Result<R, String>,
    /// How long it ran.
    pub took: Duration,
}

type Run<J, R> = Arc<dyn Fn(&J) -> R + Send + Sync>;

/// A started thread: where jobs go in, where answers come out, and the thread.
type Started<J, R> = (mpsc::Sender<J>, mpsc::Receiver<Done<J, R>>, JoinHandle<()>);

/// A job thread (see the module).
pub struct Worker<J, R> {
    name: String,
    run: Run<J, R>,
    jobs: Option<mpsc::Sender<J>>,
    results: mpsc::Receiver<Done<J, R>>,
    thread: Option<JoinHandle<()>>,
    running: bool,
    waiting: Option<J>,
    restarts: u64,
}

fn spawn<J: Send + 'static, R: Send + 'static>(
    name: &str,
    run: Run<J, R>,
) -> std::io::Result<Started<J, R>> {
    let (jobs, job_rx) = mpsc::channel::<J>();
    let (done, results) = mpsc::channel();
    let thread = std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            while let Ok(job) = job_rx.recv() {
                let t = Instant::now();
                let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(&job)))
                    .map_err(|p| {
                        p.downcast_ref::<&str>()
                            .map(|s| s.to_string())
                            .or_else(|| p.downcast_ref::<String>().cloned())
                            .unwrap_or_else(|| "a panic".into())
                    });
                let took = t.elapsed();
                if done.send(Done { job, out, took }).is_err() {
                    break;
                }
            }
        })?;
    Ok((jobs, results, thread))
}

impl<J: Send + 'static, R: Send + 'static> Worker<J, R> {
    /// A thread named `name` running `run` on each job.
    pub fn spawn(
        name: &str,
        run: impl Fn(&J) -> R + Send + Sync + 'static,
    ) -> std::io::Result<Worker<J, R>> {
        let run: Run<J, R> = Arc::new(run);
        let (jobs, results, thread) = spawn(name, run.clone())?;
        Ok(Worker {
            name: name.into(),
            run,
            jobs: Some(jobs),
            results,
            thread: Some(thread),
            running: false,
            waiting: None,
            restarts: 0,
        })
    }

    /// Gives the thread `job`: at once when it is idle, else as the one waiting job. Returns
    /// the waiting job it replaced (to be answered by the caller), if any.
    pub fn offer(&mut self, job: J) -> std::io::Result<Option<J>> {
        if self.running {
            return Ok(self.waiting.replace(job));
        }
        self.start(job)?;
        Ok(None)
    }

    fn start(&mut self, job: J) -> std::io::Result<()> {
        let sent = match &self.jobs {
            Some(jobs) => jobs.send(job).map_err(|mpsc::SendError(job)| job),
            None => Err(job),
        };
        if let Err(job) = sent {
            tracing::error!(thread = %self.name, "the job thread has gone; starting it again");
            self.restarts += 1;
            let (jobs, results, thread) = spawn(&self.name, self.run.clone())?;
            let _ = jobs.send(job);
            (self.jobs, self.results, self.thread) = (Some(jobs), results, Some(thread));
        }
        self.running = true;
        Ok(())
    }

    fn finished(&mut self, done: Done<J, R>) -> std::io::Result<Done<J, R>> {
        self.running = false;
        if let Some(next) = self.waiting.take() {
            self.start(next)?;
        }
        Ok(done)
    }

    /// A finished job's answer, if one is ready; the waiting job starts then.
    pub fn try_recv(&mut self) -> std::io::Result<Option<Done<J, R>>> {
        match self.results.try_recv() {
            Ok(done) => self.finished(done).map(Some),
            Err(_) => Ok(None),
        }
    }

    /// A finished job's answer within `timeout`.
    pub fn recv_timeout(&mut self, timeout: Duration) -> std::io::Result<Option<Done<J, R>>> {
        match self.results.recv_timeout(timeout) {
            Ok(done) => self.finished(done).map(Some),
            Err(_) => Ok(None),
        }
    }

    /// True while a job runs or waits.
    pub fn busy(&self) -> bool {
        self.running || self.waiting.is_some()
    }

    /// How many times the thread was started again.
    pub fn restarts(&self) -> u64 {
        self.restarts
    }

    /// Stops the thread: the waiting job is given back unstarted; the running one (which the
    /// caller has cancelled) is waited for up to `wait` and its answer given back.
    /// A job offered after it starts the thread again.
    pub fn stop(&mut self, wait: Duration) -> (Option<Done<J, R>>, Option<J>) {
        let waiting = self.waiting.take();
        let last = if self.running {
            self.results.recv_timeout(wait).ok()
        } else {
            None
        };
        self.jobs = None;
        if let Some(thread) = self.thread.take() {
            if last.is_some() || !self.running {
                let _ = thread.join();
            }
        }
        self.running = false;
        (last, waiting)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn recv(w: &mut Worker<u32, u32>) -> Done<u32, u32> {
        w.recv_timeout(Duration::from_secs(30)).unwrap().unwrap()
    }

    #[test]
    fn a_job_that_panics_is_answered_and_the_thread_goes_on() {
        let mut w = Worker::spawn("test", |&n: &u32| {
            assert!(n % 2 == 0, "odd job {n}");
            n * 10
        })
        .unwrap();
        for n in [1, 2, 3, 4] {
            assert!(w.offer(n).unwrap().is_none() || n > 1);
            let d = recv(&mut w);
            assert_eq!(d.job, n);
            match n % 2 {
                1 => assert!(d.out.unwrap_err().contains("odd job")),
                _ => assert_eq!(d.out.unwrap(), n * 10),
            }
        }
        assert_eq!(w.restarts(), 0);
        assert!(!w.busy());
        let (last, waiting) = w.stop(Duration::from_secs(1));
        assert!(last.is_none() && waiting.is_none());
    }

    #[test]
    fn the_newest_waiting_job_wins_and_starts_when_the_running_one_ends() {
        let (go, gate) = mpsc::channel::<()>();
        let gate = std::sync::Mutex::new(gate);
        let mut w = Worker::spawn("test", move |&n: &u32| {
            if n == 1 {
                gate.lock().unwrap().recv().unwrap();
            }
            n
        })
        .unwrap();
        assert!(w.offer(1).unwrap().is_none());
        assert!(w.offer(2).unwrap().is_none());
        assert_eq!(w.offer(3).unwrap(), Some(2));
        assert!(w.busy());
        go.send(()).unwrap();
        assert_eq!(recv(&mut w).job, 1);
        assert_eq!(recv(&mut w).job, 3);
        assert!(!w.busy());
    }

    #[test]
    fn stopping_gives_back_the_waiting_job_and_the_running_ones_answer() {
        let (go, gate) = mpsc::channel::<()>();
        let gate = std::sync::Mutex::new(gate);
        let mut w = Worker::spawn("test", move |&n: &u32| {
            gate.lock().unwrap().recv().unwrap();
            n
        })
        .unwrap();
        w.offer(1).unwrap();
        w.offer(2).unwrap();
        go.send(()).unwrap();
        let (last, waiting) = w.stop(Duration::from_secs(30));
        assert_eq!(last.unwrap().job, 1);
        assert_eq!(waiting, Some(2));
    }
}
