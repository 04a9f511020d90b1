// Shared, cached reads: places, robots, map images, objects.

import { getBlob, getJson, ApiError, type PlaceView, type RobotView, type ObjectView, type RoadmapView, type PolicySummary } from './api';
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

export function objects(p: PlaceView): Promise<MapObject[]> {
  return cached(`objects:${p.iri}`, async () => (await getJson<ObjectView[]>(`/v1/places/${placeKey(p)}/objects`)).map(mapObject));
}

/** An object's footprint as the maps draw it. */
export type Shape =
  | { kind: 'box'; length: number; width: number; height: number }
  | { kind: 'cylinder'; diameter: number; height: number }
  | { kind: 'sphere'; diameter: number };

/** An object as the maps draw it: the wire's `shape` name and `size` extents made one shape,
 *  named after its IRI, its class by local name. */
export interface MapObject {
  iri: string;
  name: string;
  class: string;
  pose: ObjectView['pose'];
  shape: Shape;
  /** "#rrggbb", or null for the default. */
  colour: string | null;
  placeholder: boolean;
  open: boolean;
}

export function mapObject(o: ObjectView): MapObject {
  const local = o.iri.split(/[#/]/).filter(Boolean).pop() ?? o.iri;
  const [x = 0.5, y = 0.5, z = 0.5] = o.size;
  const shape: Shape = o.shape === 'box'
    ? { kind: 'box', length: x, width: y, height: z }
    : o.shape === 'sphere'
      ? { kind: 'sphere', diameter: Math.max(x, y) }
      : { kind: 'cylinder', diameter: Math.max(x, y), height: z };
  return {
    iri: o.iri,
    name: local,
    class: (o.class ?? '').split(/[#/]/).pop() ?? '',
    pose: o.pose,
    shape,
    colour: o.colour || null,
    placeholder: o.placeholder,
    open: o.open,
  };
}

export function roadmap(p: PlaceView, robot: string, policy: string | null): Promise<RoadmapView> {
  const q = new URLSearchParams({ place: p.id ?? p.iri, robot });
  if (policy) q.set('policy', policy);
  return cached(`roadmap:${q}`, () => getJson<RoadmapView>(`/v1/roadmaps?${q}`));
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
  onObjects: (o: MapObject[]) => void, onError: (e: unknown) => void,
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
