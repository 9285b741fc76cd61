// The trial reference in the browser: the same curve as bowden.web.reference.TrialReference.
// Rest at the low elevation until start_s, then `repetitions` raise-and-lower minimum-jerk cycles
// x = x0 + D(10τ³ − 15τ⁴ + 6τ⁵) (Flash & Hogan 1985), then rest. The browser tests check both agree.
"use strict";

const BowdenReference = (() => {
  function endS(ref) {
    return ref.start_s + ref.repetitions * 2 * ref.movement_s;
  }

  function elevationDeg(ref, t) {
    const low = ref.low_deg;
    const elapsed = t - ref.start_s;
    if (elapsed <= 0 || t >= endS(ref)) {
      return low;
    }
    const move = ref.movement_s;
    const phase = elapsed % (2 * move);
    const raising = phase < move;
    const tau = raising ? phase / move : phase / move - 1;
    const s = tau * tau * tau * (10 - 15 * tau + 6 * tau * tau);
    const span = ref.high_deg - low;
    return raising ? low + span * s : ref.high_deg - span * s;
  }

  // The repetition in progress at t (1-based); 0 before the start, `repetitions` after the end.
  function repetition(ref, t) {
    if (t < ref.start_s) {
      return 0;
    }
    if (t >= endS(ref)) {
      return ref.repetitions;
    }
    return Math.min(ref.repetitions, 1 + Math.floor((t - ref.start_s) / (2 * ref.movement_s)));
  }

  return { elevationDeg, repetition, endS };
})();
