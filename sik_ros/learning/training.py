"""Training of SIK, PSIK, FCN and ANFIS models, with resumable checkpoints.

A checkpoint holds the model state, the optimiser and scheduler state, the step count, the RNG
states, both configs, the normaliser and the dataset manifest, so it rebuilds itself with nothing
else and a resumed run continues exactly where it stopped.
"""

from dataclasses import asdict
from pathlib import Path
import time
from typing import Callable, Dict, Optional, TYPE_CHECKING, Union

import torch
from torch.nn.parallel import DistributedDataParallel

from sik_ros.artifacts import (atomic_write, check_robot_manifest, FORMAT_VERSION,
                               library_versions)
from sik_ros.errors import ArtifactMismatch, InvalidArgument, TrainingDiverged
from sik_ros.learning import distributed
from sik_ros.learning.checkpoints import normalizer_from_dict
from sik_ros.learning.generated_data import GeneratedData
from sik_ros.learning.losses import cycle_terms, fk_error, orientation_error_deg
from sik_ros.learning.models import build_model, kl_normal, ModelConfig, TorchChain
from sik_ros.learning.provenance import device_name, Provenance
from sik_ros.learning.swarm import new_swarm, swarm_step
from sik_ros.learning.train_config import anchor_weight_at, kl_weight_at, lr_at, TrainConfig
from sik_ros.learning.training_data import data_summary, default_normalizer, TrainData
from sik_ros.learning.warm_start import (checked_normalizer, index_mean, initial_state,
                                         makes_variational, narrows, standardise_index)
from sik_ros.tables.dataset import Dataset

if TYPE_CHECKING:  # Pinocchio: a chain file's arm trains without it
    from sik_ros.kinematics.robot import Robot

#: Training rows over which a PSIK started from a SIK model standardises its index.
STANDARDISE_ROWS = 20_000


class Trainer:
    """Trains one model on one dataset, with validation, checkpoints and resume."""

    def __init__(self, robot: 'Robot', dataset: Union[Dataset, GeneratedData],
                 model_cfg: ModelConfig, train_cfg: TrainConfig, out_dir: Path):
        """A trainer of one model.

        Args:
            robot: the arm: a :class:`~sik_ros.kinematics.robot.Robot`, or a
                :class:`~sik_ros.kinematics.chain_file.ChainArm` (no Pinocchio needed).
            dataset: a dataset on disk, or rows generated on the training device
                (:class:`~sik_ros.learning.generated_data.GeneratedData`); the rows move to
                the training device once.
            model_cfg: the model.
            train_cfg: the training settings.
            out_dir: where ``last.pt`` is written.
        """
        if model_cfg.dof != robot.dof:
            raise InvalidArgument(f'model dof {model_cfg.dof} != robot dof {robot.dof}')
        if train_cfg.anchor_joint >= robot.dof:
            raise InvalidArgument(f'anchor joint {train_cfg.anchor_joint} is not one of the '
                                  f'{robot.dof} joints (0-based)')
        self.robot, self.dataset = robot, dataset
        self.model_cfg, self.cfg = model_cfg, train_cfg
        self.out_dir = Path(out_dir)
        torch.set_num_threads(train_cfg.threads)
        torch.manual_seed(train_cfg.seed)
        self.device = torch.device(train_cfg.device)
        self.norm = default_normalizer(robot, dataset)
        self.generated = isinstance(dataset, GeneratedData)
        self.data = TrainData(dataset, model_cfg.goal, train_cfg.uni_position).to(self.device)
        gen = torch.Generator().manual_seed(train_cfg.seed)
        perm = torch.randperm(len(self.data), generator=gen)
        n_val = min(train_cfg.val_rows, max(1, len(self.data) // 10))
        self.val_idx = perm[:n_val].to(self.device)
        self.train_idx = perm[n_val:].to(self.device)
        self.model = build_model(model_cfg).to(self.device)
        self.rank, self.world_size = distributed.world()
        # several processes (torchrun): gradients averaged by DDP, batches drawn per rank
        self.net = self.model
        if self.world_size > 1 and model_cfg.kind != 'anfis':
            self.net = DistributedDataParallel(self.model)
        self.fk = TorchChain(robot.chain).to(self.device)
        self.opt = torch.optim.Adam(self.model.parameters(), lr=train_cfg.lr)
        self.gen = torch.Generator().manual_seed(train_cfg.seed + 1 + 7919 * self.rank)
        # the batches' random numbers are drawn where the batches are (the CPU's: self.gen)
        self.sample_gen = self.gen if self.device.type == 'cpu' else torch.Generator(
            device=self.device).manual_seed(train_cfg.seed + 2 + 7919 * self.rank)
        self.step = 0
        self.elapsed = 0.0
        self.history = []
        self.provenance = Provenance()

    # -- losses ----------------------------------------------------------------------------------

    def _batch(self, idx: torch.Tensor):
        d = self.data
        return tuple(t[idx] for t in (d.q, d.goal, d.position, d.rot6))

    def fresh_batch(self, n: int):
        """``n`` joint configurations uniform within the limits and their goals (torch FK).

        The batch the ``uniform`` sampler trains on; :meth:`losses` takes it as ``batch``.

        Returns:
            ``(q, goal, position, rot6)``: joint values (n, dof) [rad], the model's goals (the
            position, or the position and rot6), tip positions (n, 3) [m] and the first two
            columns of the tip rotations (n, 6).
        """
        lo = torch.as_tensor(self.robot.lower, dtype=torch.float32, device=self.device)
        hi = torch.as_tensor(self.robot.upper, dtype=torch.float32, device=self.device)
        q = lo + (hi - lo) * torch.rand(n, len(lo), generator=self.sample_gen,
                                        device=self.device)
        with torch.no_grad(), torch.autocast(self.device.type, enabled=False):
            pos, rot = self.fk(q)
        rot6 = torch.cat([rot[:, :, 0], rot[:, :, 1]], 1)
        goal = pos if self.model_cfg.goal == 'position' else torch.cat([pos, rot6], 1)
        return q, goal, pos, rot6

    def _fk_error(self, x_hat: torch.Tensor, pos: torch.Tensor, rot6: torch.Tensor):
        """The FK term of normalised joints against their goals (:func:`fk_error`)."""
        return fk_error(self.fk, self.norm, self.cfg, self.model_cfg.goal == 'pose', x_hat,
                        pos, rot6)

    def losses(self, idx: torch.Tensor = None, batch=None) -> Dict[str, torch.Tensor]:
        """The loss terms of a batch: dataset row indices, or ``(q, goal, pos, rot6)``."""
        q, goal, pos, rot6 = self._batch(idx) if batch is None else batch
        g = self.norm.goal_to_net(goal)
        x = self.norm.q_to_net(q)
        out = {}
        sik = self.model_cfg.kind in ('sik', 'psik')
        if sik:
            x_hat, mu, logvar = self.net(g, x)
            if logvar is not None:
                out['kl'] = kl_normal(mu, logvar).mean()
        else:
            x_hat = self.net(g)
        out['recon'] = torch.mean((x_hat - x) ** 2)
        fk_on = self.cfg.fk_weight > 0 and self.step >= self.cfg.fk_start
        if self.cfg.fk_weight > 0:
            out['fk'] = self._fk_error(x_hat, pos, rot6)
        if sik and self.cfg.cycle_weight > 0:
            other = cycle_terms(self.model, self.norm, self.cfg, self.model_cfg.goal == 'pose',
                                mu, pos, rot6, self.sample_gen)
            out['cycle'] = other['cycle']
            if self.cfg.fk_weight > 0:
                out['fk_other'] = self._fk_error(other['x_other'], other['pos_other'],
                                                 other['rot6_other'])
        anchor = anchor_weight_at(self.cfg, self.step) if sik else 0.0
        if anchor > 0:
            out['anchor'] = torch.mean((mu[:, 0] - x[:, self.cfg.anchor_joint]) ** 2)
        fk_weight = self.cfg.fk_weight if fk_on else 0.0
        total = out['recon'] + fk_weight * (out.get('fk', 0.0) + out.get('fk_other', 0.0))
        if 'cycle' in out:
            total = total + self.cfg.cycle_weight * out['cycle']
        if 'anchor' in out:
            total = total + anchor * out['anchor']
        if 'kl' in out:
            total = total + kl_weight_at(self.cfg, self.step) * out['kl']
        out['loss'] = total
        return out

    @torch.no_grad()
    def validate(self) -> Dict[str, float]:
        """Distance error [m] (and orientation error [deg]) of decoded validation rows."""
        self.model.eval()
        errs, oerrs, losses, spreads = [], [], [], []
        for s in range(0, len(self.val_idx), 8192):
            idx = self.val_idx[s:s + 8192]
            q, goal, pos, rot6 = self._batch(idx)
            losses.append(float(self.losses(idx)['loss']) * len(idx))
            x_hat = self.predict_net(goal, q)
            if self.model_cfg.kind in ('sik', 'psik'):
                # how far apart the postures of two indices at one goal are (0: collapsed)
                g = self.norm.goal_to_net(goal)
                mu, _ = self.model.encode(g, self.norm.q_to_net(q))
                x_other = self.model.decode(g, mu.roll(1, dims=0))
                spreads.append(torch.linalg.norm(x_other - x_hat, dim=1))
            q_hat = self.norm.q_from_net(x_hat)
            p_hat, r_hat = self.fk(q_hat)
            errs.append(torch.linalg.norm(p_hat - pos, dim=1))
            if self.model_cfg.goal == 'pose':
                oerrs.append(orientation_error_deg(rot6, r_hat))
        self.model.train()
        err = torch.cat(errs)
        res = {'val_loss': sum(losses) / len(self.val_idx),
               'val_dist_mean_m': float(err.mean()), 'val_dist_median_m': float(err.median())}
        if oerrs:
            res['val_orient_mean_deg'] = float(torch.cat(oerrs).mean())
        if spreads:
            res['val_index_spread'] = float(torch.cat(spreads).mean())
        return res

    def predict_net(self, goal: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
        """Normalised joints the model predicts (SIK/PSIK: index from the true joints)."""
        g = self.norm.goal_to_net(goal)
        if self.model_cfg.kind in ('sik', 'psik'):
            mu, _ = self.model.encode(g, self.norm.q_to_net(q))
            return self.model.decode(g, mu)
        return self.model(g)

    # -- loop --------------------------------------------------------------------------------

    def run(self, max_time: Optional[float] = None,
            progress: Optional[Callable[[int, Dict], None]] = None) -> Dict:
        """Train until ``cfg.steps`` or ``max_time`` seconds of this call; checkpoint on exit.

        One loop for both optimisers: a gradient step (SIK, PSIK, FCN) or a particle swarm
        step (ANFIS, the paper's solver), then validation, checkpoints and progress. A
        ``KeyboardInterrupt`` (Ctrl-C; ``sik-train`` also turns SIGTERM into one) checkpoints
        the steps done so far before it goes on up.
        """
        try:
            return self._run(max_time, progress)
        except KeyboardInterrupt:
            self.save()
            raise

    def _run(self, max_time: Optional[float], progress) -> Dict:
        pso = self.model_cfg.kind == 'anfis'
        step = self._pso_step if pso else self._gradient_step
        t0 = time.perf_counter()
        start_elapsed = self.elapsed
        self.model.train()
        last = {}
        per_step = (self.cfg.pso_batch if pso else self.cfg.batch_size) * self.world_size
        self.provenance.start(device_name(self.device), self.world_size, self.step)
        while self.step < self.cfg.steps:
            last = step()
            self.step += 1
            self.elapsed = start_elapsed + time.perf_counter() - t0
            self.provenance.stepped(self.step, per_step, time.perf_counter() - t0)
            if self.step % self.cfg.eval_every == 0 or self.step == self.cfg.steps:
                lr = {} if pso else {'lr': lr_at(self.cfg, self.step - 1)}
                rec = {'step': self.step, 'elapsed_s': round(self.elapsed, 1), **lr, **last,
                       **self.validate()}
                self.history.append(rec)
                last = rec
            if self.step % self.cfg.checkpoint_every == 0:
                self.save()
            if progress:
                progress(self.step, last)
            if self._stop(max_time is not None and time.perf_counter() - t0 >= max_time):
                break
        if not pso and self.step > 0 and (not self.history
                                          or self.history[-1]['step'] != self.step):
            # stopped between validations (--max-time): the run ends with its figures
            last = {'step': self.step, 'elapsed_s': round(self.elapsed, 1),
                    'lr': lr_at(self.cfg, self.step - 1), **last, **self.validate()}
            self.history.append(last)
        self.save()
        return last

    def seconds_per_step(self, steps: int = 8) -> float:
        """Wall time of one gradient step here [s], timed over ``steps`` after one warm-up.

        It trains the model as it times it: use a throw-away trainer. An ANFIS's step is a
        swarm step.
        """
        step = self._pso_step if self.model_cfg.kind == 'anfis' else self._gradient_step
        step()
        self._synchronize()
        t0 = time.perf_counter()
        for _ in range(steps):
            step()
        self._synchronize()
        return (time.perf_counter() - t0) / steps

    def _synchronize(self) -> None:
        """Wait for the device's queued work (a GPU's), so that a timer sees it done."""
        if self.device.type == 'cuda':
            torch.cuda.synchronize(self.device)

    def _stop(self, mine: bool) -> bool:
        """Whether to stop now: with several processes, as soon as any of them would."""
        if self.world_size == 1 or self.net is self.model:
            return mine
        flag = torch.tensor([1.0 if mine else 0.0], device=self.device)
        torch.distributed.all_reduce(flag, op=torch.distributed.ReduceOp.MAX)
        return bool(flag.item() > 0)

    def _gradient_step(self) -> Dict[str, float]:
        """One optimiser step on a random batch; the losses it saw."""
        for group in self.opt.param_groups:
            group['lr'] = lr_at(self.cfg, self.step)
        if self.cfg.sampler == 'uniform':
            args = {'batch': self.fresh_batch(self.cfg.batch_size)}
        else:
            pick = torch.randint(len(self.train_idx), (self.cfg.batch_size,),
                                 generator=self.sample_gen, device=self.device)
            args = {'idx': self.train_idx[pick]}
        with torch.autocast(self.device.type, dtype=torch.bfloat16, enabled=self.cfg.bf16):
            out = self.losses(**args)
        if not torch.isfinite(out['loss']):
            bad = float(out['loss'].detach())
            raise TrainingDiverged(
                f'loss became {bad} at step {self.step}; the last good '
                f'checkpoint is kept in {self.out_dir} (lower --lr or resume from it)')
        self.opt.zero_grad(set_to_none=True)
        out['loss'].backward()
        self.opt.step()
        return {k: float(v.detach()) if torch.is_tensor(v) else float(v) for k, v in out.items()}

    @torch.no_grad()
    def _pso_step(self) -> Dict[str, float]:
        """One particle swarm step of an ANFIS (:mod:`~sik_ros.learning.swarm`); its best loss."""
        if getattr(self, '_pso', None) is None:
            self._pso = new_swarm(self.model.params_flat.detach(), self.cfg.pso_particles,
                                  self.gen)
        pick = torch.randint(len(self.train_idx), (self.cfg.pso_batch,), generator=self.gen)
        q, goal, _, _ = self._batch(self.train_idx[pick.to(self.device)])
        state = swarm_step(self._pso, self.model_cfg, self.norm.goal_to_net(goal),
                           self.norm.q_to_net(q), self.gen)
        self.model.params_flat.copy_(state['gbest'])
        return {'loss': float(state['gbest_f'])}

    # -- checkpoints -------------------------------------------------------------------------

    def checkpoint(self) -> Dict:
        """Everything needed to rebuild the model and resume training."""
        ckpt = {
            'kind': 'sik_checkpoint', 'format_version': FORMAT_VERSION,
            'model_config': asdict(self.model_cfg), 'train_config': asdict(self.cfg),
            'normalizer': asdict(self.norm), 'robot': self.robot.manifest(),
            'dataset': data_summary(self.dataset),
            'model_state': {k: v.detach().cpu() for k, v in self.model.state_dict().items()},
            'optimizer_state': self.opt.state_dict(),
            'step': self.step, 'elapsed_s': self.elapsed, 'history': list(self.history),
            'rng': {'torch': torch.get_rng_state(), 'batches': self.gen.get_state()},
            'versions': library_versions(), 'trained': self.provenance.record(self.step),
        }
        if self.sample_gen is not self.gen:
            ckpt['rng']['device_batches'] = self.sample_gen.get_state()
        if getattr(self, '_pso', None) is not None:
            ckpt['pso'] = {k: v.clone() for k, v in self._pso.items()}
        return ckpt

    def save(self) -> Path:
        """Write ``last.pt`` atomically in the output directory (rank 0 only)."""
        path = self.out_dir / 'last.pt'
        if self.rank != 0:
            return path
        self.out_dir.mkdir(parents=True, exist_ok=True)
        with atomic_write(path) as tmp:
            torch.save(self.checkpoint(), tmp)
        return path

    def initialise(self, ckpt: Dict, source: str) -> None:
        """Start from the weights of another checkpoint or exported model (a warm start).

        The robot and the normaliser must match (rows generated afresh take the weights'); the
        optimiser, the step count and the schedule start afresh. The model config must match,
        or widen the checkpoint's (:func:`~sik_ros.learning.warm_start.widened_state`), narrow
        it (a smaller index learned afresh, the old index's mean over training rows folded into
        the decoder: :func:`~sik_ros.learning.warm_start.narrowed_state`), or be its PSIK
        (:func:`~sik_ros.learning.warm_start.variational_state`, the index then standardised).
        """
        found = ModelConfig.from_dict(ckpt['model_config'])
        mean = None
        if narrows(found, self.model_cfg):
            q, goal, _, _ = self._batch(self.train_idx[:STANDARDISE_ROWS])
            mean = index_mean(ckpt, goal.cpu(), q.cpu())
        state = initial_state(self.model.state_dict(), ckpt, self.model_cfg, source, mean)
        check_robot_manifest(f'--init {source}', self.robot.manifest(), ckpt['robot'])
        self.provenance.started_from(source, ckpt)
        self.norm = checked_normalizer(ckpt, self.norm, source, not self.generated)
        self.model.load_state_dict(state)
        if makes_variational(found, self.model_cfg):
            q, goal, _, _ = self._batch(self.train_idx[:STANDARDISE_ROWS])
            standardise_index(self.model, self.norm.goal_to_net(goal), self.norm.q_to_net(q))

    def restore(self, ckpt: Dict) -> None:
        """Continue from a checkpoint of the same model on the same robot and dataset."""
        found = ModelConfig.from_dict(ckpt['model_config'])
        if found != self.model_cfg:
            raise ArtifactMismatch('checkpoint model config', asdict(self.model_cfg),
                                   ckpt['model_config'])
        check_robot_manifest('checkpoint', self.robot.manifest(), ckpt['robot'])
        if ckpt['dataset'] != data_summary(self.dataset):
            raise ArtifactMismatch('checkpoint dataset', data_summary(self.dataset),
                                   ckpt['dataset'])
        self.norm = normalizer_from_dict(ckpt['normalizer'])  # a warm start's, if it had one
        self.model.load_state_dict(ckpt['model_state'])
        self.opt.load_state_dict(ckpt['optimizer_state'])
        self.step = int(ckpt['step'])
        self.elapsed = float(ckpt['elapsed_s'])
        self.history = list(ckpt['history'])
        torch.set_rng_state(ckpt['rng']['torch'])
        self.gen.set_state(ckpt['rng']['batches'])
        if self.sample_gen is not self.gen:
            if 'device_batches' in ckpt['rng']:
                self.sample_gen.set_state(ckpt['rng']['device_batches'])
            else:  # a run resumed on a GPU: a stream of its own from here
                self.sample_gen.manual_seed(self.cfg.seed + 2 + self.step)
        if self.rank > 0:  # the checkpoint holds rank 0's stream: the others draw their own
            self.gen.manual_seed(self.cfg.seed + 1 + 7919 * self.rank + self.step)
            if self.sample_gen is not self.gen:
                self.sample_gen.manual_seed(self.cfg.seed + 2 + 7919 * self.rank + self.step)
        self.provenance = Provenance.from_checkpoint(ckpt)
        if 'pso' in ckpt:
            self._pso = {k: v.clone() for k, v in ckpt['pso'].items()}
