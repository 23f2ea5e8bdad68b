//! A swarm's robots shared among a batch's threads for the whole of a world-step.
//!
//! A step of a 1,000-robot world makes about fourteen passes over its robots (the motors, the
//! contact checks, the arcs, the sensors, ...), most of them 20 to 80 µs of work, between
//! serial sections (rapier's step, the contact marks). Handed to rayon one by one, each pass
//! woke the pool's other thread, which had gone to sleep in the serial section before it: on
//! these 2-core virtual machines a wake-up costs tens of µs, so a pass of 50 µs took 66 µs on
//! two threads and the world stepped only 1.12 times faster on two threads than on one
//! (issue 54; `perf` put 14 % of the samples in the kernel's futex and scheduler).
//!
//! A swarm's step instead takes the pool's other threads for the whole step
//! ([`World::step_team`](super::World::step_team), which `Env::step` and `Env::reset` run in):
//! each runs [`Shared::help`], waiting for work without sleeping, while the calling thread steps
//! the world and posts each pass to the team ([`Team::each`]) as chunks that any member claims,
//! the caller included: the world's passes and the env's (the actions, the observations). A
//! pass then costs a few atomic operations to share, not a wake-up.
//!
//! The caller never waits for a chunk nobody has claimed: it claims chunks itself until none
//! is left, and waits only for those a helper is running. So a helper that never starts (its
//! thread busy with another world of the batch) costs nothing but the parallelism, and a pass
//! gives the same results whoever runs its chunks (each chunk depends only on its robots and
//! what the pass reads), as rayon's passes did. A helper with nothing to do runs the pool's
//! other jobs (`rayon::yield_now`), so a batch of several swarms keeps every thread busy.
//!
//! One `unsafe` block (besides the vector kernels' dispatch and the counting allocator): a
//! posted pass borrows the caller's stack, and a helper reaches it through a raw pointer. The
//! caller withdraws the pointer and waits until no helper is inside the pass before the pass
//! returns (or unwinds), so no helper can reach it afterwards: see [`Team::each_beside`] and
//! [`Shared::help`]. The tests below run passes on 1 to 8 threads, with a panic in a helper's
//! part.

use std::any::Any;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::ptr;
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU64, AtomicUsize, Ordering::SeqCst};
use std::sync::{Arc, Mutex};

/// Robots a chunk of a pass holds: the flags a pass writes (a byte a robot) then fill a cache
/// line, so that two threads seldom write one line (with 32, every line was two chunks and the
/// contact checks took 76 µs a step on two threads against 55-58 with 64 or 128); larger chunks
/// would share a few hundred robots unevenly.
pub(crate) const CHUNK: usize = 64;

/// Spins of an idle helper between looks for the pool's other jobs.
const SPINS_BETWEEN_YIELDS: u32 = 64;

/// A world's team: the state its caller and helpers share. A cloned world gets a team of its
/// own (two worlds stepped at once must not post to one team).
#[derive(Debug, Default)]
pub(super) struct Team {
    shared: Arc<Shared>,
}

impl Clone for Team {
    fn clone(&self) -> Self {
        Self::default()
    }
}

#[derive(Debug, Default)]
struct Shared {
    /// The pass posted now (null: none).
    job: AtomicPtr<Job<'static>>,
    /// Helpers between taking `job` and leaving it.
    busy: AtomicUsize,
    /// Whether helpers should keep waiting for passes (a step is under way).
    open: AtomicBool,
}

/// A posted pass.
struct Job<'a> {
    /// Claims and runs items until none is left: from the back (a helper) or the front.
    take_part: &'a (dyn Fn(bool) + Sync),
    /// The first panic of a helper's part, for the caller to resume.
    panic: Mutex<Option<Box<dyn Any + Send>>>,
}

impl std::fmt::Debug for Job<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Job")
    }
}

impl Shared {
    /// A helper's loop: takes part in every pass posted until the step ends.
    fn help(&self) {
        let mut idle = 0u32;
        while self.open.load(SeqCst) {
            // Waiting only reads `job` (no write to the line the caller posts on, whatever the
            // number of helpers).
            let job = self.job.load(SeqCst);
            if job.is_null() {
                idle += 1;
                if idle.is_multiple_of(SPINS_BETWEEN_YIELDS) {
                    rayon::yield_now();
                } else {
                    std::hint::spin_loop();
                }
                continue;
            }
            // Counted busy, then the job looked at again: a caller that has withdrawn it and
            // then reads `busy` as 0 knows that no helper will reach it (both sequentially
            // consistent). A job posted anew at the same address is as live as the first.
            self.busy.fetch_add(1, SeqCst);
            if self.job.load(SeqCst) != job {
                self.busy.fetch_sub(1, SeqCst);
                continue;
            }
            // SAFETY: `job` was posted by `Team::each_beside`, which withdraws it and waits for
            // `busy` to reach 0 before the job's stack frame ends; this helper counted itself
            // busy before finding it still posted, so the frame is live until the `fetch_sub`
            // below.
            let posted = unsafe { &*job };
            if let Err(panic) = catch_unwind(AssertUnwindSafe(|| (posted.take_part)(true))) {
                let mut first = posted.panic.lock().unwrap_or_else(|e| e.into_inner());
                first.get_or_insert(panic);
            }
            self.busy.fetch_sub(1, SeqCst);
            // Done with this pass: wait for it to be withdrawn rather than enter it again.
            while self.job.load(SeqCst) == job && self.open.load(SeqCst) {
                std::hint::spin_loop();
            }
            idle = 0;
        }
    }
}

impl Team {
    /// A handle on this team (the same one, where `clone` makes a new team).
    pub(super) fn share(&self) -> Self {
        Self {
            shared: Arc::clone(&self.shared),
        }
    }

    /// Runs `work` with the current rayon pool's other threads helping with the passes it
    /// posts over `items` items (robots): at most one helper per two chunks of them, since a
    /// helper without a chunk to claim only spins. Without a pool (or with one thread) `work`
    /// just runs, and the passes run in order on this thread; inside a scope of this team
    /// already (whose helpers are there), too.
    pub(super) fn scope<R>(&self, items: usize, work: impl FnOnce() -> R) -> R {
        let most = (items.div_ceil(CHUNK) / 2).max(1);
        let helpers = rayon::current_num_threads().saturating_sub(1).min(most);
        let shared = &self.shared;
        if rayon::current_thread_index().is_none() || helpers == 0 || shared.open.load(SeqCst) {
            return work();
        }
        shared.open.store(true, SeqCst);
        let done = rayon::in_place_scope(|s| {
            for _ in 0..helpers {
                let team = Arc::clone(shared);
                s.spawn(move |_| team.help());
            }
            let done = catch_unwind(AssertUnwindSafe(work));
            shared.open.store(false, SeqCst);
            done
        });
        done.unwrap_or_else(|panic| resume_unwind(panic))
    }

    /// Runs `f` on every item, items shared among the team (see [`Team::each_beside`]).
    pub(super) fn each<T: Send>(
        &self,
        items: impl IntoIterator<Item = T>,
        f: impl Fn(usize, T) + Sync,
    ) {
        self.each_beside(
            items,
            || (),
            |_: &mut (), first, item| f(first, item),
            || (),
        );
    }

    /// Posts `f` over `items` to the team, runs `beside` on this thread, then claims items
    /// until none is left and waits for the helpers' last ones. Item k is the k-th chunk of
    /// [`CHUNK`] robots: `f` gets the index of its first robot with it. Each member makes its
    /// own scratch with `init` before its first item. Outside a scope (a world that does not
    /// share its robots, or a pool of one thread) the items run in order after `beside`, on
    /// this thread, without being gathered: so every pass is written once, for both. A panic
    /// in any part is resumed here, after every helper has left the pass.
    pub(super) fn each_beside<T: Send, S>(
        &self,
        items: impl IntoIterator<Item = T>,
        init: impl Fn() -> S + Sync,
        f: impl Fn(&mut S, usize, T) + Sync,
        beside: impl FnOnce(),
    ) {
        let shared = &*self.shared;
        if !shared.open.load(SeqCst) {
            beside();
            let mut scratch = init();
            for (k, item) in items.into_iter().enumerate() {
                f(&mut scratch, k * CHUNK, item);
            }
            return;
        }
        let slots: Vec<Mutex<Option<T>>> = items.into_iter().map(|t| Mutex::new(Some(t))).collect();
        // The caller claims items from the front, helpers from the back, until they meet:
        // each thread then keeps the same robots pass after pass (in its own core's cache; a
        // robot whose thread changed from pass to pass was read from the other core's).
        let ends = Ends::new(slots.len());
        let take_part = |from_back: bool| {
            let mut scratch = None;
            while let Some(k) = ends.claim(from_back) {
                let item = slots[k].lock().unwrap_or_else(|e| e.into_inner()).take();
                if let Some(item) = item {
                    f(scratch.get_or_insert_with(&init), k * CHUNK, item);
                }
            }
        };
        let job = Job {
            take_part: &take_part,
            panic: Mutex::new(None),
        };
        let posted: *const Job<'_> = &job;
        shared
            .job
            .store(posted.cast::<Job<'static>>().cast_mut(), SeqCst);
        let mine = catch_unwind(AssertUnwindSafe(|| {
            beside();
            take_part(false);
        }));
        // Withdraw the job, then wait for every helper that saw it to leave it: after this no
        // helper can reach `job`, `take_part` or `slots` (see `Shared::help`).
        shared.job.store(ptr::null_mut(), SeqCst);
        while shared.busy.load(SeqCst) != 0 {
            std::hint::spin_loop();
        }
        if let Err(panic) = mine {
            resume_unwind(panic);
        }
        let theirs = job.panic.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(panic) = theirs {
            resume_unwind(panic);
        }
    }
}

/// The team of one world's step ([`World::step_team`](super::World::step_team)).
#[derive(Debug)]
pub struct StepTeam {
    pub(super) team: Option<Team>,
    pub(super) robots: usize,
}

impl StepTeam {
    /// Runs `work`, a step of the world (or its reset), with the team there for every pass
    /// over its robots that the step posts, the task's as well as the world's.
    pub fn scope<R>(&self, work: impl FnOnce() -> R) -> R {
        match &self.team {
            Some(team) => team.scope(self.robots, work),
            None => work(),
        }
    }

    /// Runs `f` on every item of `items`, chunk k of a pass over the world's robots (or its
    /// agents, one a robot): [`CHUNK`] of them, `f` getting the index of the first. A swarm
    /// shares them among its team (inside [`StepTeam::scope`]; see [`Team::each_beside`]);
    /// another world runs them in order. `f` must depend only on its item and what it reads,
    /// so that the results do not depend on who runs it.
    pub(crate) fn each<T: Send>(
        &self,
        items: impl IntoIterator<Item = T>,
        f: impl Fn(usize, T) + Sync,
    ) {
        match &self.team {
            Some(team) => team.each(items, f),
            None => {
                for (k, item) in items.into_iter().enumerate() {
                    f(k * CHUNK, item);
                }
            }
        }
    }
}

/// The items of a pass not yet claimed: `front..back`, packed in one word so that both ends
/// move atomically together.
struct Ends(AtomicU64);

impl Ends {
    fn new(n: usize) -> Self {
        Self(AtomicU64::new((n as u64) << 32))
    }

    /// Claims the first (or last) item not yet claimed, if any.
    fn claim(&self, from_back: bool) -> Option<usize> {
        let mut now = self.0.load(SeqCst);
        loop {
            let (front, back) = (now & 0xffff_ffff, now >> 32);
            if front >= back {
                return None;
            }
            let (next, k) = if from_back {
                (now - (1 << 32), back - 1)
            } else {
                (now + 1, front)
            };
            match self.0.compare_exchange_weak(now, next, SeqCst, SeqCst) {
                Ok(_) => return Some(k as usize),
                Err(seen) => now = seen,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
    }

    #[test]
    fn every_item_runs_once_whoever_claims_it_and_a_pass_sees_the_last_ones_results() {
        for threads in [1, 2, 3, 8] {
            let team = Team::default();
            let mut values: Vec<u64> = (0..1000).collect();
            pool(threads).install(|| {
                team.scope(1000, || {
                    for round in 0..50u64 {
                        let items: Vec<&mut [u64]> = values.chunks_mut(CHUNK).collect();
                        team.each(items, |_, chunk| chunk.iter_mut().for_each(|v| *v += round));
                    }
                })
            });
            let expected: Vec<u64> = (0..1000).map(|v| v + (0..50).sum::<u64>()).collect();
            assert_eq!(values, expected, "{threads} threads");
        }
    }

    #[test]
    fn beside_runs_while_the_items_are_shared_and_each_member_makes_its_own_scratch() {
        let team = Team::default();
        let mut values = vec![0u32; 512];
        let mut beside_ran = false;
        let inits = AtomicUsize::new(0);
        pool(2).install(|| {
            team.scope(1000, || {
                let items: Vec<&mut [u32]> = values.chunks_mut(CHUNK).collect();
                team.each_beside(
                    items,
                    || {
                        inits.fetch_add(1, SeqCst);
                        7u32
                    },
                    |seven, _, chunk| chunk.iter_mut().for_each(|v| *v = *seven),
                    || beside_ran = true,
                );
            })
        });
        assert!(beside_ran);
        assert!(values.iter().all(|&v| v == 7));
        let members = inits.load(SeqCst);
        assert!(
            (1..=2).contains(&members),
            "{members} scratches for 2 members"
        );
    }

    #[test]
    fn a_panic_in_a_pass_reaches_the_caller_and_the_team_can_step_again() {
        let team = Team::default();
        let caught = pool(2).install(|| {
            catch_unwind(AssertUnwindSafe(|| {
                team.scope(1000, || {
                    team.each(0..64, |_, i: usize| assert!(i != 40, "item 40"));
                })
            }))
        });
        assert!(caught.is_err());
        let mut values = [1u8; 100];
        pool(2).install(|| {
            team.scope(1000, || {
                let items: Vec<&mut [u8]> = values.chunks_mut(CHUNK).collect();
                team.each(items, |_, chunk| chunk.iter_mut().for_each(|v| *v = 2));
            })
        });
        assert!(values.iter().all(|&v| v == 2));
    }
}
