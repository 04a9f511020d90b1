// Shared, cached reads: places, robots, map images, objects.

import { getBlob, getJson, ApiError, type PlaceView, type RobotView, type ObjectView, type Roadmap, type PolicySummary } from './api';
import type { MapCanvas } from './mapview';

const cache = new Map<string, Promise<unknown>>();

function cached<T>(key: string, f: () => Promise<T>): Promise<T> {
  let p = cache.get(key) as Promise<T> | undefined;
  if (!p) {
    p = f();
    cache.set(key, p);
    p.catch(() => cache.delete(key));
  }
  return p;
}

export function forget(prefix = ''): void {
  for (const k of [...cache.keys()]) if (k.startsWith(prefix)) cache.delete(k);
}

export const places = () => cached('places', () => getJson<PlaceView[]>('/v1/places'));
export const robots = () => cached('robots', () => getJson<RobotView[]>('/v1/robots'));
export const policies = () => cached('policies', () => getJson<PolicySummary[]>('/v1/policies'));

export function placeKey(p: PlaceView): string {
  return encodeURIComponent(p.id ?? p.iri);
}

export function mapImage(p: PlaceView): Promise<ImageBitmap> {
  return cached(`map:${p.iri}`, async () => {
    const blob = await getBlob(`/v1/places/${placeKey(p)}/map.png`);
    return createImageBitmap(blob);
  });
}

export function objects(p: PlaceView): Promise<ObjectView[]> {
  return cached(`objects:${p.iri}`, async () => (await getJson<unknown[]>(`/v1/places/${placeKey(p)}/objects`)).map(normaliseObject));
}

/** An object as the contract has it. Also takes the variant with `shape` as a name and `size`
 *  as [x, y, z] extents, `colour` as "#rrggbb" and `open` for `is_open`. */
export function normaliseObject(raw: unknown): ObjectView {
  const o = raw as Record<string, unknown>;
  const iri = String(o.iri ?? '');
  const local = iri.split(/[#/]/).filter(Boolean).pop() ?? iri;
  const pose = (o.pose ?? {}) as Record<string, number>;
  let shape = o.shape as ObjectView['shape'] | string;
  if (typeof shape === 'string' || !shape) {
    const size = (Array.isArray(o.size) ? o.size : [0.5, 0.5, 0.5]) as number[];
    const kind = typeof shape === 'string' ? shape : 'box';
    shape = kind === 'box'
      ? { kind: 'box', length: size[0], width: size[1], height: size[2] }
      : kind === 'sphere'
        ? { kind: 'sphere', diameter: Math.max(size[0], size[1]) }
        : { kind: 'cylinder', diameter: Math.max(size[0], size[1]), height: size[2] };
  }
  let colour = o.colour as ObjectView['colour'] | string | null;
  let srgbHex: string | null = null;
  if (typeof colour === 'string') {
    srgbHex = colour;
    colour = null;
  }
  return {
    iri,
    id: (o.id as string | null) ?? null,
    name: (o.name as string) ?? local,
    class: String(o.class ?? '').split(/[#/]/).pop() ?? '',
    pose: { x: pose.x ?? 0, y: pose.y ?? 0, z: pose.z ?? 0, yaw: pose.yaw ?? 0 },
    shape,
    colour: colour as ObjectView['colour'],
    colourHex: srgbHex,
    placeholder: Boolean(o.placeholder),
    is_open: (o.is_open as boolean | null) ?? (o.open as boolean | null) ?? null,
  };
}

export function roadmap(p: PlaceView, robot: string, policy: string | null): Promise<Roadmap> {
  const q = new URLSearchParams({ place: p.id ?? p.iri, robot });
  if (policy) q.set('policy', policy);
  return cached(`roadmap:${q}`, () => getJson<Roadmap>(`/v1/roadmaps?${q}`));
}

/** The floors and, for each, the places (rooms, corridors, ...) whose parent chain leads to it. */
export interface FloorIndex {
  byIri: Map<string, PlaceView>;
  buildings: PlaceView[];
  floors: PlaceView[];
  floorOf: (p: PlaceView) => PlaceView | null;
  areasOn: (floor: PlaceView) => PlaceView[];
}

export function indexPlaces(all: PlaceView[]): FloorIndex {
  const byIri = new Map(all.map((p) => [p.iri, p]));
  const floorOf = (p: PlaceView): PlaceView | null => {
    const seen = new Set<string>();
    let cur: PlaceView | undefined = p;
    while (cur && !seen.has(cur.iri)) {
      if (cur.map || cur.kind === 'floor') return cur;
      seen.add(cur.iri);
      cur = cur.parent ? byIri.get(cur.parent) : undefined;
    }
    return null;
  };
  const floors = all.filter((p) => p.map || p.kind === 'floor').sort((a, b) => a.name.localeCompare(b.name));
  const buildings = all.filter((p) => p.kind === 'building').sort((a, b) => a.name.localeCompare(b.name));
  const areasOn = (floor: PlaceView) =>
    all.filter((p) => p !== floor && p.boundary && p.boundary.length >= 3 && floorOf(p)?.iri === floor.iri);
  return { byIri, buildings, floors, floorOf, areasOn };
}

/** A missing endpoint (the contract's new ones, before they land) as a readable message. */
export function missing(e: unknown): boolean {
  return e instanceof ApiError && (e.status === 404 || e.status === 405) && e.code !== 'not_found_place';
}

/** Puts `floor` on the map canvas `m`: its frame at once, its image when it arrives (unless
 * `alive()` has turned false; a failure goes to `onError`), then marks the canvas ready and
 * hands the floor's objects to `onObjects` when they arrive. */
export async function showFloorOn(
  m: MapCanvas, floor: PlaceView, alive: () => boolean,
  onObjects: (o: ObjectView[]) => void, onError: (e: unknown) => void,
): Promise<void> {
  m.setMap(null, floor.map ?? null);
  m.canvas.dataset.floor = floor.id ?? floor.iri;
  try {
    if (floor.map) {
      const img = await mapImage(floor);
      if (!alive()) return;
      m.setMap(img, floor.map);
    }
  } catch (e) {
    onError(e);
  }
  m.canvas.dataset.ready = '1';
  objects(floor).then((o) => { if (alive()) onObjects(o); }, () => undefined);
}
