//! The device's own worker threads. Rendering never touches rayon's global pool (the host
//! application may use it too), and dropping the pool joins every thread so that a device
//! release or a library unload leaves no thread behind.

use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

type Task = Box<dyn FnOnce() + Send + 'static>;

pub struct WorkerPool {
    sender: Mutex<Option<Sender<Task>>>,
    workers: Vec<JoinHandle<()>>,
}

impl WorkerPool {
    pub fn new(thread_count: usize) -> WorkerPool {
        let (sender, receiver) = channel::<Task>();
        let receiver = Arc::new(Mutex::new(receiver));
        let workers = (0..thread_count.max(1))
            .map(|i| {
                let receiver = Arc::clone(&receiver);
                std::thread::Builder::new()
                    .name(format!("cavetrace-{i}"))
                    .spawn(move || worker_loop(&receiver))
                    .expect("spawning a render thread")
            })
            .collect();
        WorkerPool {
            sender: Mutex::new(Some(sender)),
            workers,
        }
    }

    pub fn thread_count(&self) -> usize {
        self.workers.len()
    }

    /// Queues a task; tasks run in submission order as workers become free.
    pub fn submit(&self, task: impl FnOnce() + Send + 'static) {
        if let Some(sender) = self
            .sender
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
        {
            // A send only fails when every worker is gone, i.e. during shutdown.
            let _ = sender.send(Box::new(task));
        }
    }
}

fn worker_loop(receiver: &Mutex<Receiver<Task>>) {
    loop {
        let task = {
            let guard = receiver.lock().unwrap_or_else(|e| e.into_inner());
            guard.recv()
        };
        match task {
            // A panicking task must not take the worker down with it.
            Ok(task) => {
                let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(task));
            }
            Err(_) => return,
        }
    }
}

impl Drop for WorkerPool {
    fn drop(&mut self) {
        // Closing the channel ends each worker once the queue is drained.
        self.sender.lock().unwrap_or_else(|e| e.into_inner()).take();
        for worker in self.workers.drain(..) {
            let _ = worker.join();
        }
    }
}

/// Runs a parallel BVH build on a rayon pool that exists only for this call. obvhs and the
/// accel layer parallelise through rayon on the calling thread's pool; a scoped pool keeps that
/// work off the application's global rayon pool and joins its threads before returning, so no
/// thread outlives the call (a library unload leaves none behind).
pub fn with_build_pool<R: Send>(thread_count: usize, build: impl FnOnce() -> R + Send) -> R {
    let mut build = Some(build);
    let scoped = rayon::ThreadPoolBuilder::new()
        .num_threads(thread_count.max(1))
        .thread_name(|i| format!("cavetrace-build-{i}"))
        .build_scoped(
            |thread| thread.run(),
            |pool| pool.install(|| (build.take().expect("runs once"))()),
        );
    match scoped {
        Ok(result) => result,
        // No threads could be started: build on this thread (rayon then runs sequentially
        // inside a one-thread pool, or the global pool as a last resort).
        Err(_) => (build.take().expect("not run yet"))(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn runs_every_task_and_joins_on_drop() {
        let done = Arc::new(AtomicUsize::new(0));
        let pool = WorkerPool::new(3);
        assert_eq!(pool.thread_count(), 3);
        for _ in 0..100 {
            let done = Arc::clone(&done);
            pool.submit(move || {
                done.fetch_add(1, Ordering::SeqCst);
            });
        }
        pool.submit(|| panic!("a failing task"));
        drop(pool);
        assert_eq!(done.load(Ordering::SeqCst), 100);
    }
}
