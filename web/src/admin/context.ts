/**
 * What every admin screen is given. The shell (main.ts) signs in, loads the venue named by the
 * route and mounts one screen at a time; a screen talks to the server only through `api` and keeps
 * the venue's revision current through `setVenue`, so that the next write's If-Match is right.
 */
import type { Venue } from '../shared/api-types';
import type { AdminApi } from './api';
import type { PlanMap } from './planmap';

export interface AdminContext {
  /** The signed-in API client (token header, If-Match, server messages as AdminError). */
  api: AdminApi;
  /** The venue as last read or written (its `revision` is what If-Match sends). */
  venue(): Venue;
  /** Re-read the venue from the server (after another tab's change, or a job's end). */
  refresh(): Promise<Venue>;
  /**
   * The venue's videos or jobs changed (an upload, a walk path, a quality map or an evaluation done):
   * its checklist reads them again, and says a step done (a failed read changes nothing).
   */
  recheck(): void;
  /** Keep a venue document a write answered (or its new revision). */
  setVenue(v: Venue): void;
  /** The floor the admin is working on (a floor id of the venue). */
  floor(): string;
  /** A Leaflet plan of the current floor, in metres, inside `el` (the caller removes it on unmount). */
  planMap(el: HTMLElement): PlanMap;
  /** Say something to screen reader users (polite status, or an assertive alert for errors). */
  announce(message: string, assertive?: boolean): void;
  /**
   * Report a failed call (added by W1): the server's message as an alert, prefixed by what was being
   * done ("Saving the scale: ..."); a stale write (412) says "changed since you opened it" and shows
   * a "Reload the venue" button that re-reads it and mounts the screen again. AbortErrors are ignored.
   */
  fail(e: unknown, doing?: string): void;
  /** Go to another screen of this venue (e.g. 'walk-path' with ?video=NAME). */
  go(screen: string, params?: Record<string, string>): void;
  /** The route's query parameters (e.g. which video the walk path screen edits). */
  params(): URLSearchParams;
}

/** A screen: mounted into `root`, returns its clean-up (stop timers, streams, maps). */
export type Mount = (root: HTMLElement, ctx: AdminContext) => () => void;
