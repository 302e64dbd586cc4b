//! The run of a yarn scene: its model set up (`build.rs`), the start state relaxed without gravity
//! (`skintight_knit::implicit_euler::ImplicitEuler::relax_observed`, a damped Newton minimisation with the
//! grips held), then backward Euler time steps (`ImplicitEuler::step`), a frame written every
//! `1 / (frame_rate_hz · dt_s)` steps (`output.rs`), and a checkpoint kept so that a stopped run resumes
//! (`checkpoint.rs`).
//!
//! Why a struct: the run's state outlives each phase (the clock of every session, the checkpoint's
//! figures, the sequence being written, the result's counters), and each phase — relaxing, writing a frame,
//! finishing — is a method on it, so the step loop of [`run`] reads as the run goes. `YarnRun` holds what
//! is fixed for the run (`RunContext`) apart from the stepper, so that the relaxation's observer
//! (`RelaxObserver`) can borrow the first while the stepper is busy; `Stepping` is what the steps change.
//! The Newton reports are read in two places only (`record_newton`, `Relaxed::take_report`).
//!
//! Units: SI (s, m); wall-clock times in s.

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use serde::Serialize;
use skintight_knit::PeriodicPattern;
use skintight_knit::frame_sequence::SequenceWriter;
use skintight_knit::implicit_euler::{ImplicitEuler, ImplicitEulerState, StepError, StepReport};
use skintight_knit::newton::{NewtonParams, NewtonReport, StopReason};
use skintight_knit::patch::PatchModel;

use super::build::patch_model;
use super::checkpoint::{CHECKPOINT_FORMAT, CHECKPOINT_VERSION, YarnRunCheckpoint, YarnRunPhase};
use super::error::YarnSceneError;
use super::output::{
    YarnSimulationResult, centre_of_mass, sequence_meta, vertex_sources, write_shapes,
};
use super::spec::YarnScene;

/// Settings of [`run`] beyond the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct YarnRunParams {
    /// Continue from `out/checkpoint.json` ([`YarnRunCheckpoint`]) when there is one; it must have been
    /// written for the same scene. Without it (or when there is none) the run starts from the beginning
    /// and a checkpoint left in `out` is deleted.
    pub resume: bool,
    /// Wall-clock time between checkpoints during the relaxation of the start state (s); the time steps
    /// write one after every frame.
    pub checkpoint_interval_s: f64,
    /// Wall-clock time between progress reports during the relaxation (s).
    pub relax_progress_interval_s: f64,
}

impl Default for YarnRunParams {
    fn default() -> Self {
        Self {
            resume: false,
            checkpoint_interval_s: 60.0,
            relax_progress_interval_s: 2.0,
        }
    }
}

/// Progress after a written frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FrameProgress {
    /// The frame just written (0 = the start).
    pub frame: usize,
    /// Frames the run will write.
    pub frame_count: usize,
    /// Simulated time (s).
    pub time_s: f64,
    /// Newton iterations so far.
    pub newton_iterations: usize,
    /// Smallest centreline distance over yarn diameter so far (while relaxing: of the start state, not
    /// measured again until frame 0 is written).
    pub min_distance_over_diameter: f64,
    /// Whether the start state is still being relaxed (then `frame` is 0 and not yet written; reported
    /// every few seconds of wall-clock time).
    pub relaxing: bool,
    /// Newton iterations of the relaxation so far.
    pub relax_newton_iterations: usize,
}

/// Runs `scene` (its pattern read from `pattern_path`) and writes into `out`: the frame sequence
/// (`sequence.json`, `vertex_sources.npy`, `frames/*.npy`), `yarns.obj` and `yarns.glb` of the last frame,
/// and `result.json`. `progress` is called every few seconds while the start state relaxes
/// (`relaxing: true`) and after every written frame; returning `Break` stops the run there (the outputs are
/// then those of the frames so far, with `stopped: true`; during the relaxation frame 0 is the state
/// reached).
///
/// **Checkpoints** ([`YarnRunCheckpoint`]): `out/checkpoint.json` is written during the relaxation every
/// `params.checkpoint_interval_s` and when stopped, and after every frame; with `params.resume` a run
/// continues from it, writing the same frames as an uninterrupted run. It is deleted when the run
/// completes. `seconds` and `relax_seconds` of the result add up the wall-clock time of every session.
pub fn run(
    scene: &YarnScene,
    pattern_path: &Path,
    out: &Path,
    params: &YarnRunParams,
    mut progress: impl FnMut(&FrameProgress) -> ControlFlow<()>,
) -> Result<YarnSimulationResult, YarnSceneError> {
    let (mut run, saved) = YarnRun::new(scene, pattern_path, out, params)?;
    let (mut stepping, mut stopped) = run.start(saved, &mut progress)?;
    if !stopped {
        // Frame 0 written, the steps start from here (a resumed run: its checkpoint's frame); report it.
        if stepping.step == 0 {
            run.checkpoint(&stepping)?;
        }
        stopped = progress(&run.ctx.report(&stepping.result)).is_break();
    }
    while !stopped && stepping.step < run.ctx.steps {
        let r = run.sim.step()?;
        stepping.record(&r);
        if stepping.step % run.ctx.per_frame == 0 {
            stopped = run.frame(&mut stepping, r.time, &mut progress)?;
        }
    }
    if !stopped && stepping.step % run.ctx.per_frame != 0 {
        // The last step between two frames: written as a last, shorter frame.
        let time = run.sim.time();
        run.push_frame(&mut stepping, time)?;
        let _ = progress(&run.ctx.report(&stepping.result));
    }
    run.finish(stepping, stopped)
}

/// What is fixed for a run: its inputs, its clock and its time grid.
struct RunContext<'a> {
    scene: &'a YarnScene,
    pattern_path: &'a Path,
    out: &'a Path,
    params: &'a YarnRunParams,
    /// When this session started.
    start: Instant,
    /// Wall-clock time of the earlier sessions (s).
    seconds_before: f64,
    /// Yarn diameter (m).
    diameter: f64,
    /// Time steps of the whole run.
    steps: usize,
    /// Time steps per frame.
    per_frame: usize,
    /// Frames the run writes (frame 0 included).
    frame_count: usize,
    /// Held vertices (clamped or moved by grips), ascending.
    held_vertices: Vec<usize>,
}

impl RunContext<'_> {
    /// Wall-clock time of the run over every session (s).
    fn elapsed(&self) -> f64 {
        self.seconds_before + self.start.elapsed().as_secs_f64()
    }

    /// The error of a checkpoint whose state the stepper refuses.
    fn bad_state(&self, e: StepError) -> YarnSceneError {
        YarnSceneError::Input(format!(
            "{}: {e}; run without --resume to start again",
            YarnRunCheckpoint::path(self.out).display()
        ))
    }

    /// The progress after the frame `result` was last written.
    fn report(&self, result: &YarnSimulationResult) -> FrameProgress {
        FrameProgress {
            frame: result.frames - 1,
            frame_count: self.frame_count,
            time_s: result.simulated_time_s,
            newton_iterations: result.newton_iterations,
            min_distance_over_diameter: result.min_distance_m / self.diameter,
            relaxing: false,
            relax_newton_iterations: result.relax_newton_iterations,
        }
    }
}

/// A run in progress: its context and its stepper.
struct YarnRun<'a> {
    ctx: RunContext<'a>,
    sim: ImplicitEuler,
}

/// What the time steps change: the sequence being written and the result so far.
struct Stepping {
    /// The model at frame 0 (its patch and masses give the outputs).
    model: PatchModel,
    writer: SequenceWriter,
    result: YarnSimulationResult,
    /// Centre of mass at frame 0 (m).
    com0: [f64; 3],
    /// Time steps done.
    step: usize,
}

/// The start state's relaxation as it went: Newton iterations over every session, whether it converged,
/// whether the caller stopped it, and its wall-clock time over every session (s).
struct Relaxed {
    iterations: usize,
    converged: bool,
    stopped: bool,
    seconds: f64,
}

impl<'a> YarnRun<'a> {
    /// Checks the settings, reads the pattern, sets up the model and its stepper, and reads the checkpoint
    /// to resume (with `params.resume`; otherwise deletes any).
    fn new(
        scene: &'a YarnScene,
        pattern_path: &'a Path,
        out: &'a Path,
        params: &'a YarnRunParams,
    ) -> Result<(Self, Option<YarnRunCheckpoint>), YarnSceneError> {
        let start = Instant::now();
        for (name, v) in [
            ("checkpoint interval", params.checkpoint_interval_s),
            ("progress interval", params.relax_progress_interval_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(YarnSceneError::Input(format!("{name} {v} s must be ≥ 0")));
            }
        }
        let pattern = PeriodicPattern::read(pattern_path)
            .map_err(|e| YarnSceneError::Input(e.to_string()))?;
        let (model, prescribed) = patch_model(scene, &pattern)?;
        let mut held_vertices: Vec<usize> = prescribed.iter().map(|p| p.vertex).collect();
        held_vertices.sort_unstable();
        let sim = ImplicitEuler::new(model, scene.time_stepping(), prescribed)?;
        let saved = if params.resume {
            YarnRunCheckpoint::read(out)?
        } else {
            YarnRunCheckpoint::remove(out)?;
            None
        };
        if let Some(c) = &saved {
            c.check_scene(scene, out)?;
        }
        let (steps, per_frame) = scene.steps();
        let ctx = RunContext {
            scene,
            pattern_path,
            out,
            params,
            start,
            seconds_before: saved.as_ref().map_or(0.0, |c| c.seconds),
            diameter: 2.0 * sim.model().radius(),
            steps,
            per_frame,
            frame_count: 1 + steps.div_ceil(per_frame),
            held_vertices,
        };
        Ok((Self { ctx, sim }, saved))
    }

    /// The state the steps start from: a stepping checkpoint's, or the relaxed start state (the relaxation
    /// resumed from a relaxing checkpoint) with frame 0 written. Also whether the caller stopped the
    /// relaxation.
    fn start(
        &mut self,
        saved: Option<YarnRunCheckpoint>,
        progress: &mut impl FnMut(&FrameProgress) -> ControlFlow<()>,
    ) -> Result<(Stepping, bool), YarnSceneError> {
        let (done, seconds_before) = match saved {
            Some(c) if c.phase == YarnRunPhase::Stepping => return Ok((self.resumed(c)?, false)),
            Some(c) => {
                self.sim
                    .restore_state(c.state)
                    .map_err(|e| self.ctx.bad_state(e))?;
                (c.relax_newton_iterations, c.relax_seconds)
            }
            None => (0, 0.0),
        };
        let relaxed = self.relax(done, seconds_before, progress)?;
        Ok((self.first_frame(&relaxed)?, relaxed.stopped))
    }

    /// Relaxes the start state without gravity for the iterations the scene has left after `done`, with a
    /// checkpoint every `checkpoint_interval_s` and progress every `relax_progress_interval_s`.
    fn relax(
        &mut self,
        done: usize,
        seconds_before: f64,
        progress: &mut impl FnMut(&FrameProgress) -> ControlFlow<()>,
    ) -> Result<Relaxed, YarnSceneError> {
        let scene = self.ctx.scene;
        let remaining = scene.relax_max_iterations.saturating_sub(done);
        let mut relaxed = Relaxed {
            iterations: done,
            converged: false,
            stopped: false,
            seconds: seconds_before,
        };
        if remaining > 0 {
            let newton = NewtonParams {
                max_iterations: remaining,
                max_factorizations: 5 * remaining,
                ..scene.newton
            };
            let mut observer =
                RelaxObserver::new(&self.ctx, &self.sim, done, seconds_before, progress);
            let report = self
                .sim
                .relax_observed(&newton, &mut |model: &PatchModel, x: &[f64]| {
                    observer.observe(model, x)
                })?;
            if let Some(e) = observer.failure {
                return Err(e);
            }
            relaxed.take_report(&report);
        }
        // This session's set-up (the periodic rest solve) counts with the relaxation.
        relaxed.seconds = seconds_before + self.ctx.start.elapsed().as_secs_f64();
        Ok(relaxed)
    }

    /// Starts the sequence at the relaxed state: frame 0 written, the result at frame 0.
    fn first_frame(&self, relaxed: &Relaxed) -> Result<Stepping, YarnSceneError> {
        let ctx = &self.ctx;
        let model = self.sim.model().clone();
        let meta = sequence_meta(
            ctx.scene,
            ctx.pattern_path,
            &model,
            ctx.per_frame,
            &ctx.held_vertices,
        );
        let mut writer = SequenceWriter::create(ctx.out, meta, &vertex_sources(&model))?;
        writer.push(0.0, self.sim.state())?;
        let result = YarnSimulationResult::at_start(
            ctx.scene,
            ctx.pattern_path,
            &model,
            self.sim.state(),
            ctx.held_vertices.len(),
            (relaxed.iterations, relaxed.converged, relaxed.seconds),
        );
        Ok(Stepping {
            com0: centre_of_mass(&model, self.sim.state()),
            model,
            writer,
            result,
            step: 0,
        })
    }

    /// Continues the steps from a stepping checkpoint: its state restored, its sequence reopened.
    fn resumed(&mut self, c: YarnRunCheckpoint) -> Result<Stepping, YarnSceneError> {
        let model = self.sim.model().clone();
        let result = c
            .result
            .expect("a stepping checkpoint holds the result (checked when read)");
        self.sim
            .restore_state(c.state)
            .map_err(|e| self.ctx.bad_state(e))?;
        let writer = SequenceWriter::resume(self.ctx.out, result.frames)?;
        Ok(Stepping {
            model,
            writer,
            result,
            com0: c.centre_of_mass_start_m,
            step: c.steps,
        })
    }

    /// Writes the checkpoint of the steps done.
    fn checkpoint(&self, s: &Stepping) -> Result<(), YarnSceneError> {
        let ctx = &self.ctx;
        YarnRunCheckpoint {
            format: CHECKPOINT_FORMAT.into(),
            version: CHECKPOINT_VERSION,
            scene: ctx.scene.clone(),
            phase: YarnRunPhase::Stepping,
            relax_newton_iterations: s.result.relax_newton_iterations,
            steps: s.step,
            result: Some(s.result.clone()),
            centre_of_mass_start_m: s.com0,
            seconds: ctx.elapsed(),
            relax_seconds: s.result.relax_seconds,
            state: self.sim.save_state(),
        }
        .write(ctx.out)
    }

    /// Appends the stepper's state as the frame at `time` (s).
    fn push_frame(&self, s: &mut Stepping, time: f64) -> Result<(), YarnSceneError> {
        s.writer.push(time, self.sim.state())?;
        s.result.frames += 1;
        s.result.min_distance_over_diameter = s.result.min_distance_m / self.ctx.diameter;
        Ok(())
    }

    /// A frame of the steps at `time` (s): written, checkpointed (unless it is the last) and reported;
    /// whether the caller stops the run.
    fn frame(
        &self,
        s: &mut Stepping,
        time: f64,
        progress: &mut impl FnMut(&FrameProgress) -> ControlFlow<()>,
    ) -> Result<bool, YarnSceneError> {
        self.push_frame(s, time)?;
        if s.step < self.ctx.steps {
            self.checkpoint(s)?;
        }
        Ok(progress(&self.ctx.report(&s.result)).is_break())
    }

    /// The end of the run (complete or stopped): the final figures, the last frame's shapes and
    /// `result.json` written, and the checkpoint deleted when the run is complete.
    fn finish(
        self,
        mut s: Stepping,
        stopped: bool,
    ) -> Result<YarnSimulationResult, YarnSceneError> {
        let ctx = &self.ctx;
        let x = self.sim.state();
        let result = &mut s.result;
        result.stopped = stopped;
        result.min_distance_over_diameter = result.min_distance_m / ctx.diameter;
        result.kinetic_energy_j = self.sim.kinetic_energy();
        let com1 = centre_of_mass(&s.model, x);
        result.centre_of_mass_displacement_m = std::array::from_fn(|k| com1[k] - s.com0[k]);
        write_shapes(&s.model, x, ctx.out)?;
        result.seconds = ctx.elapsed();
        let stepping = result.seconds - result.relax_seconds;
        result.seconds_per_step = stepping / result.steps.max(1) as f64;
        result.seconds_per_newton_iteration = stepping / result.newton_iterations.max(1) as f64;
        result.write(ctx.out)?;
        if !stopped {
            YarnRunCheckpoint::remove(ctx.out)?;
        }
        Ok(s.result)
    }
}

impl Stepping {
    /// Counts a time step into the result.
    fn record(&mut self, r: &StepReport) {
        self.step += 1;
        let result = &mut self.result;
        result.steps = self.step;
        result.simulated_time_s = r.time;
        result.substeps += r.substeps;
        result.rejected_substeps += r.rejected_substeps;
        result.min_distance_m = result.min_distance_m.min(r.min_distance);
        result.max_contacts = result.max_contacts.max(r.contacts);
        result.max_candidates = result.max_candidates.max(r.candidates);
        result.max_sphere_contacts = result.max_sphere_contacts.max(r.sphere_contacts);
        record_newton(result, &r.newton);
    }
}

/// Counts a step's Newton solve into the result (the one place the steps read the Newton report).
fn record_newton(result: &mut YarnSimulationResult, newton: &NewtonReport) {
    result.newton_iterations += newton.iterations;
    result.newton_iterations_max_step = result.newton_iterations_max_step.max(newton.iterations);
    result.factorizations += newton.factorizations;
    result.newton_timings.add(&newton.figures.timings);
    result.unconverged_steps += usize::from(!newton.converged);
    result.max_residual = result.max_residual.max(newton.residual);
}

impl Relaxed {
    /// Takes the relaxation's Newton report (the one place the relaxation reads it).
    fn take_report(&mut self, report: &NewtonReport) {
        self.stopped = report.stop == StopReason::Cancelled;
        self.iterations += report.iterations;
        self.converged = report.converged;
    }
}

/// Told every Newton iteration of the relaxation: reports progress every `relax_progress_interval_s` and
/// writes a relaxing checkpoint every `checkpoint_interval_s` and when the caller stops the run.
struct RelaxObserver<'r, P> {
    ctx: &'r RunContext<'r>,
    progress: &'r mut P,
    /// When this session's relaxation started.
    start: Instant,
    last_checkpoint: Instant,
    last_report: Instant,
    /// Relaxation seconds of the earlier sessions.
    seconds_before: f64,
    /// Newton iterations over every session.
    done: usize,
    /// Smallest centreline distance of the state the relaxation started from (m).
    min_distance: f64,
    /// The velocities of a relaxing checkpoint (at rest).
    zero: Vec<f64>,
    /// A checkpoint that could not be written (the relaxation stops).
    failure: Option<YarnSceneError>,
}

impl<'r, P: FnMut(&FrameProgress) -> ControlFlow<()>> RelaxObserver<'r, P> {
    fn new(
        ctx: &'r RunContext<'r>,
        sim: &ImplicitEuler,
        done: usize,
        seconds_before: f64,
        progress: &'r mut P,
    ) -> Self {
        let start = Instant::now();
        Self {
            ctx,
            progress,
            start,
            last_checkpoint: Instant::now(),
            last_report: Instant::now(),
            seconds_before,
            done,
            min_distance: sim.model().min_distance(sim.state()),
            zero: vec![0.0; sim.state().len()],
            failure: None,
        }
    }

    /// One accepted Newton iteration at the state `x` of `model`.
    fn observe(&mut self, model: &PatchModel, x: &[f64]) -> ControlFlow<()> {
        self.done += 1;
        let mut flow = ControlFlow::Continue(());
        if self.last_report.elapsed().as_secs_f64() >= self.ctx.params.relax_progress_interval_s {
            self.last_report = Instant::now();
            flow = (self.progress)(&FrameProgress {
                frame: 0,
                frame_count: self.ctx.frame_count,
                time_s: 0.0,
                newton_iterations: 0,
                min_distance_over_diameter: self.min_distance / self.ctx.diameter,
                relaxing: true,
                relax_newton_iterations: self.done,
            });
        }
        let interval = self.ctx.params.checkpoint_interval_s;
        if flow.is_break() || self.last_checkpoint.elapsed().as_secs_f64() >= interval {
            self.last_checkpoint = Instant::now();
            if let Err(e) = self.checkpoint(model, x).write(self.ctx.out) {
                self.failure = Some(e);
                return ControlFlow::Break(());
            }
        }
        flow
    }

    /// The relaxing checkpoint at the state `x` of `model`.
    fn checkpoint(&self, model: &PatchModel, x: &[f64]) -> YarnRunCheckpoint {
        YarnRunCheckpoint {
            format: CHECKPOINT_FORMAT.into(),
            version: CHECKPOINT_VERSION,
            scene: self.ctx.scene.clone(),
            phase: YarnRunPhase::Relaxing,
            relax_newton_iterations: self.done,
            steps: 0,
            result: None,
            centre_of_mass_start_m: [0.0; 3],
            seconds: self.ctx.elapsed(),
            relax_seconds: self.seconds_before + self.start.elapsed().as_secs_f64(),
            state: ImplicitEulerState {
                time: 0.0,
                halvings: 0,
                shift: 0.0,
                x: x.to_vec(),
                v: self.zero.clone(),
                frames: model.frames_snapshot(),
            },
        }
    }
}
