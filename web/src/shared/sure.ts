/**
 * The one line between "sure" and "probably", shared by the phone (its sentences, the plan, when
 * "Where am I?" films on) and the admin page (an evaluation walk's counts): the engine's
 * aggregate.SURE.
 */
/**
 * An answer under this confidence, though not "not sure", is said as "You are probably ...": the
 * confidence's promise (docs/formats.md: at least 80 % of the answers at or above it within 2 m)
 * and the one under which "Where am I?" films on. Under it a fifth of the answers or more were further than 2 m off
 * on the venue families we never tuned on, against 1-2 % above it (docs/benchlog.md, "Said as
 * probably"); a place heard as a fact is walked to.
 */
export const SURE = 0.8;

/**
 * Whether an answer that is not "not sure" is said as sure ("You are ...") rather than "probably"
 * (NaN: probably): the one test of the line, for the sentence, the gist, the plan and the admin.
 */
export const isSure = (a: { confidence: number }): boolean => a.confidence >= SURE;
