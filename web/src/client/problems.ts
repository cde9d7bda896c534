/** What the user hears when "Where am I?" cannot answer: what went wrong and what to do about it. */
import { ApiProblem, Unreachable } from './api';
import { CameraProblem } from './camera';

export const NO_FRAMES =
  'This venue has no modelled frames yet, so omninav cannot tell where you are here. Ask the venue’s administrator to upload and model a video of it.';
export const NO_LENS =
  'This venue has no lens profile yet. Ask the venue’s administrator to add the lens it was filmed with.';

/** What a user hears when the venue was modelled with a setting this app cannot apply (a newer server's). */
export const APP_OUTDATED =
  'This copy of omninav is older than this building’s map. Close omninav and open it again to update it.';

/**
 * The venue's server reads another record than this app makes (an app cached offline, a server
 * upgraded). `outdated`: the sizes may agree, but the map needs a setting this app does not know;
 * the user hears only that the app is too old (the settings' names mean nothing spoken), and
 * `why` keeps them for whoever debugs it.
 */
export class RecordMismatch extends Error {
  constructor(
    readonly why: string,
    outdated = false,
  ) {
    super(
      outdated
        ? APP_OUTDATED
        : `This copy of omninav makes feature records that the server cannot read (${why}). Close omninav and open it again to update it.`,
    );
  }
}

export const MAP_UPDATED = 'The building’s map has just been updated; the next question uses the new one.';

/** The server refused features made with the venue's settings from before it was modelled anew. */
export const mapUpdated = (e: unknown): boolean =>
  e instanceof ApiProblem && e.status === 400 && typeof e.body.venue_settings_id === 'number';

/**
 * A locate error of a record made with settings `sentId`: a settings mismatch that names the very
 * settings sent is no "map updated" (reading the venue again cannot mend it): a plain 400 then.
 */
export function staleOrNot(e: unknown, sentId: number): unknown {
  return mapUpdated(e) && (e as ApiProblem).body.venue_settings_id === sentId
    ? new ApiProblem(400, (e as ApiProblem).message)
    : e;
}

export function problemText(e: unknown): string {
  if (e instanceof Unreachable || e instanceof CameraProblem || e instanceof RecordMismatch) return e.message;
  if (e instanceof ApiProblem) {
    // features made with the settings the venue had before it was modelled anew (the session reloads it)
    if (mapUpdated(e)) return MAP_UPDATED;
    if (e.status === 409) return NO_FRAMES;
    if (e.status === 429) return 'Too many questions at once. Wait a moment, then press Where am I? again.';
    if (e.status === 404) return 'This venue is no longer on the server. Choose another venue in Settings.';
    return `The server could not answer: ${e.message}`;
  }
  return `Something went wrong: ${(e as Error).message ?? e}`;
}
