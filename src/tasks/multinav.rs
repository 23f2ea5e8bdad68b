//! Multi-robot navigation (PettingZoo `multinav_v0`): every robot drives to its own goal; the
//! robots are obstacles to one another (their discs block each other's rays and rapier resolves
//! their contacts). Each robot is an agent with the Nav observation and reward; a robot that
//! reaches its goal is terminated as an agent and parks there (its actions are ignored), still
//! an obstacle for the others. The episode terminates when every robot has arrived.

use rapier2d::math::Vector;

use super::nav;
use crate::scenario::Scenario;
use crate::world::World;

/// Per-world state of the multi-robot navigation task.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct MultiNav {
    /// Each robot's goal (m).
    pub goals: Vec<Vector>,
    prev_distance: Vec<f32>,
    /// Robots that have reached their goal.
    pub arrived: Vec<bool>,
}

impl MultiNav {
    /// The task for `n` robots (goals at the origin until the first reset).
    pub fn new(n: usize) -> Self {
        Self {
            goals: vec![Vector::ZERO; n],
            prev_distance: vec![0.0; n],
            arrived: vec![false; n],
        }
    }

    /// Starts an episode toward `goals` (robots already placed).
    pub fn reset(&mut self, world: &World, goals: &[Vector]) {
        self.goals = goals.to_vec();
        self.prev_distance = goals
            .iter()
            .zip(&world.robots)
            .map(|(g, r)| (*g - r.position).length())
            .collect();
        self.arrived = vec![false; goals.len()];
    }

    /// Rewards and arrivals after a step: `rewards[i]` and `terminated[i]` per robot; returns
    /// whether every robot has now arrived.
    pub fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        terminated: &mut [bool],
    ) -> bool {
        for i in 0..self.goals.len() {
            if self.arrived[i] {
                rewards[i] = 0.0;
                terminated[i] = true;
                continue;
            }
            let j = nav::judge_robot(world, i, self.goals[i], &mut self.prev_distance[i], cfg);
            rewards[i] = j.reward;
            self.arrived[i] = j.success;
            terminated[i] = j.success;
        }
        self.arrived.iter().all(|a| *a)
    }

    /// Writes every robot's Nav observation, one block after another.
    pub fn observe(&self, world: &World, cfg: &Scenario, obs: &mut [f32]) {
        for (i, block) in obs.chunks_exact_mut(nav::OBS_DIM).enumerate() {
            nav::observe_robot(world, i, self.goals[i], cfg, block);
        }
    }
}
