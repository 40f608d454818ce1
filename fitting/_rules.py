"""`DiagnosisRules`: every threshold of the diagnosis's decision, in one frozen object.

``fitting.diagnose(..., rules=DiagnosisRules(z=3.0))`` changes one; the decision itself is
`fitting._select`. Each field is documented here and nowhere else. How far the search goes
is not a threshold of the rule: `fitting.diagnose`'s ``max_added`` and ``max_steps``.
"""

import dataclasses


@dataclasses.dataclass(frozen=True)
class DiagnosisRules:
    """The five numbers the diagnosis decides by (`fitting._select`).

    - `blocks`: the record is cut into this many contiguous time blocks of equal duration.
      A block is the unit of evidence: the held-out error of the model with and without
      an effect is compared block by block, so blocks must be longer than the residual's
      correlation (a drift, a mismatched presliding curve), and there must be enough of
      them for a standard error (20: each block is 5 % of the record).
    - `folds`: the blocks are dealt to this many folds in turn (block ``b`` to fold
      ``b % folds``); each fold is held out once while the model is refitted on the other
      blocks, so every sample is held out exactly once and every regime the record visits
      more than once is in every training set (4: a quarter of the record held out).
    - `z`: an effect is accepted when the mean over blocks of ``log(SSE_current /
      SSE_effect)`` (held out, block by block) exceeds `z` standard errors of that mean:
      a one-sided test on block-level evidence, which carries the residual's
      autocorrelation within each block. Log ratios, not SSE differences: an effect felt
      where the motion is fast or accelerating (a mass) improves a few blocks by far more
      than the rest, and on differences those few blocks make the standard error and hide
      an effect that improves every block (measured: a true mass removing 93 % of the
      held-out SSE, every block improved, z 2.2 on differences, 3.3 on log ratios). The
      standard error is the larger of the blocks taken as independent and the blocks of
      one fold taken together (cluster-robust, by fold sums): the blocks of a fold share
      one fitted model, so an error of that fit moves them together (measured: an offset
      file's extra asymmetry, z 2.4 with independent blocks, its between-fold variance
      4.4 times the within-fold one, 1.5 by folds). 2.0 is a false-alarm rate of about
      2.5 % per candidate with independent blocks and at most about 7 % where the 4 fold
      sums decide (Student t, 3 degrees of freedom); the rule cross-validates only `tried`
      candidates per round, and the effect must also be physical. The same `z` says
      which qualifying candidates the data do not tell apart from the best (their mean
      block log ratio to it under `z` standard errors): where the best is a base-model
      change, such an effect is added instead (`fitting._select`).
    - `min_gain`: the share of the held-out SSE an effect must be shown to remove: its
      mean block log ratio, less `z` standard errors, must exceed
      ``log(1 / (1 - min_gain))`` (the one-sided test of `z`, against this margin
      instead of 0). Significant is not the same as relevant: where the base
      model cannot reproduce the truth exactly, any effect absorbs a little of the
      mismatch, and does so evenly over the blocks (measured: an offset on a clean file
      of the fitted model's family with a different presliding curve, 1.7 % of the
      held-out SSE at z 2.45). 0.01: an effect that cannot be shown to lower the held-out
      RMSE by half a per cent is not worth a parameter.
    - `tried`: per round, this many candidates are cross-validated: those with the lowest
      training error after their full refit, among those whose refit removes more than its
      expected optimism ``2 q s^2`` (q added coordinates, ``s^2`` the current model's
      residual variance: what fitting noise removes, not a threshold) and that can qualify
      (physical, converged); when none qualifies, the pairs of those are.
    """

    blocks: int = 20
    folds: int = 4
    z: float = 2.0
    tried: int = 3
    min_gain: float = 0.01

    def __post_init__(self):
        if self.folds < 2 or self.blocks < self.folds:
            raise ValueError(f"need folds >= 2 and blocks >= folds, got folds={self.folds}, "
                             f"blocks={self.blocks}")
        if self.z <= 0 or self.tried < 1:
            raise ValueError(f"need z > 0 and tried >= 1, got z={self.z}, tried={self.tried}")
        if not 0 <= self.min_gain < 1:
            raise ValueError(f"need 0 <= min_gain < 1, got min_gain={self.min_gain}")
