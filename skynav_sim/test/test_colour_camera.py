# SPDX-License-Identifier: Apache-2.0
"""The synthetic colour camera: physically sensible colours, a white balance that keeps grey grey, every encoding
decoded back to the rendered light, recordings with the contract's topics, and the UV/green camera unchanged."""

import hashlib

import numpy as np
import pytest
import yaml
from scipy.ndimage import binary_erosion
from scipy.spatial.transform import Rotation

from skynav_core.camera import EquidistantCamera
from skynav_core.colour import (
    COLOUR_ENCODINGS,
    LINEAR_FULL_SCALE,
    decode_compressed,
    decode_image,
    linear_to_srgb,
)
from skynav_core.names import (
    CAMERA_FRAME,
    COLOUR_CAMERA_INFO,
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    GROUND_TRUTH_MASK,
    GROUND_TRUTH_POSE,
)
from skynav_core.recording.bag import open_bag
from skynav_core.recording.typestore import typestore
from skynav_sim import recording
from skynav_sim.colour_sensor import ColourSensor, compressed, daylight_white_balance, encode
from skynav_sim.materials import BAND_RANGES, Surface
from skynav_sim.recording import CameraOutput, captures
from skynav_sim.render import CameraPose, Renderer
from skynav_sim.robot import CAMERA_HEIGHT
from skynav_sim.scenarios import ScenarioParameters, build
from skynav_sim.sky import RGB, TIMES_OF_DAY, UV_GREEN, Sky
from skynav_sim.world import generate
from skynav_testing import run_skynav

pytestmark = pytest.mark.heavy(45)

SMALL = ['--size', '96x72', '--length', '1.0', '--speed', '1.0']
# A camera at a mower's camera height turned to look 10 degrees above the horizon: half its view is ground.
SIDEWAYS = CameraPose(np.array([0.0, 0.0, CAMERA_HEIGHT]), Rotation.from_euler('y', 80, degrees=True))


def _directions(count: int = 20000) -> np.ndarray:
    """Return random upward unit directions (N, 3), map frame."""
    d = np.random.default_rng(5).normal(size=(count, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.3
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.fixture(scope='module')
def garden():
    return generate('garden', 1)


@pytest.fixture(scope='module')
def colour_view(garden):
    """A small rendered colour view of the garden (forenoon, some clouds) and its camera."""
    camera = EquidistantCamera.for_field_of_view(64, 48, np.radians(200))
    frame = build('teach', garden, ScenarioParameters(route_length=1.0, speed=1.0, cloud_cover=0.3), 1)[0]
    return Renderer(garden, camera, RGB).render(frame.pose, Sky(frame.hours, 0.3, cloud_seed=1)), camera


@pytest.mark.parametrize('time', ['sunrise', 'morning', 'forenoon', 'noon'])
def test_the_clear_sky_is_bluer_than_the_direct_sunlight(time):
    sky = Sky(TIMES_OF_DAY[time])
    d = _directions()
    clear = {band: np.median(sky.radiance(band, d[d @ sky.sun < np.cos(np.radians(20))], np.zeros(3))) for band in RGB}
    assert clear['blue'] / clear['red'] > 1.2 * sky.direct['blue'] / sky.direct['red']
    assert sky.diffuse['blue'] / sky.diffuse['red'] > 1.5 * sky.direct['blue'] / sky.direct['red']
    assert clear['blue'] > clear['green'] > clear['red']  # blue sky, in the white-balance-free radiance too


def test_a_low_sun_is_red():
    sunrise, noon = Sky(TIMES_OF_DAY['sunrise']), Sky(TIMES_OF_DAY['noon'])
    assert sunrise.direct['red'] / sunrise.direct['blue'] > 2.5 * noon.direct['red'] / noon.direct['blue']
    assert sunrise.direct['red'] > sunrise.direct['green'] > sunrise.direct['blue']


@pytest.mark.parametrize(('time', 'spread'), [('morning', 1.3), ('forenoon', 1.08), ('noon', 1.05)])
def test_clouds_are_bright_and_near_neutral_in_the_visible_bands(time, spread):
    # white-balanced as the camera does: a cloud's channels lie within `spread` of each other (a morning's clouds
    # are lit by a warmer sun), far closer than the clear sky's, and it outshines the clear sky in every band
    sky = Sky(TIMES_OF_DAY[time], cloud_cover=0.5, cloud_seed=4)
    d = _directions()
    clouds = sky.cloud_density(d, np.zeros(3))
    away = d @ sky.sun < np.cos(np.radians(20))
    gains = np.array(daylight_white_balance())

    def colour(where):
        return np.array([np.median(sky.radiance(band, d[where & away], np.zeros(3))) for band in RGB]) * gains

    cloud, clear = colour(clouds > 0.9), colour(clouds == 0)
    assert cloud.max() / cloud.min() < spread
    assert cloud.max() / cloud.min() < 0.8 * clear.max() / clear.min()
    assert np.all(cloud > 2 * clear)


def test_material_colours():
    red, green, blue = (BAND_RANGES[band].mean(axis=1) for band in RGB)
    chromaticity = green / (red + green + blue)
    for leafy in (Surface.GRASS, Surface.FOLIAGE, Surface.HEDGE):
        assert chromaticity[leafy] > 0.4 and green[leafy] < 0.15  # green and dark
        assert chromaticity[leafy] > chromaticity[Surface.SAND] + 0.08
    for reddish in (Surface.BRICK, Surface.ROOF_TILE):
        assert red[reddish] > 1.8 * green[reddish] and red[reddish] > 2 * blue[reddish]
    for pale in (Surface.LIME_PLASTER, Surface.CONCRETE, Surface.LIMESTONE, Surface.SAND):
        assert green[pale] > 0.2 and max(red[pale], blue[pale]) / min(red[pale], blue[pale]) < 1.6
    for ranges in BAND_RANGES.values():
        assert np.all(ranges[:, 0] <= ranges[:, 1]) and np.all((ranges > 0) & (ranges < 1))


def test_grass_renders_greener_than_sand(make_flat_world):
    camera = EquidistantCamera.for_field_of_view(64, 48, np.radians(200))
    sky = Sky(TIMES_OF_DAY['forenoon'])
    world = make_flat_world([])
    grass = Renderer(world, camera, RGB).render(SIDEWAYS, sky)
    world.terrain.materials[:] = Surface.SAND
    sand = Renderer(world, camera, RGB).render(SIDEWAYS, sky)
    ground = ~grass.sky & grass.inside
    assert ground.sum() > 100

    def chroma(view):
        rgb = view.rgb()[ground] * np.array(daylight_white_balance())
        return np.median(rgb[:, 1] / rgb.sum(axis=1))

    assert chroma(grass) > chroma(sand) + 0.05


def test_a_grey_surface_renders_grey_under_the_daylight_white_balance(make_flat_world, monkeypatch):
    # every band reflects 30 %: under the clear synthetic noon sun the white-balanced ground has equal channels
    grey = {band: np.full((len(Surface), 2), 0.3) for band in ('uv', 'blue', 'green', 'red')}
    monkeypatch.setattr('skynav_sim.render.BAND_RANGES', grey)
    camera = EquidistantCamera.for_field_of_view(64, 48, np.radians(200))
    view = Renderer(make_flat_world([]), camera, RGB).render(SIDEWAYS, Sky(TIMES_OF_DAY['noon']))
    ground = binary_erosion(~view.sky & view.inside)
    sensor = ColourSensor(full_well=1e7, read_noise=0.0, blur_sigma=0.0)  # noise far below the test's 1 %
    signal = sensor.capture(view.rgb(), view.inside, np.random.default_rng(0))[ground]
    assert ground.sum() > 100
    assert np.allclose(signal[:, 0], signal[:, 1], rtol=0.01) and np.allclose(signal[:, 2], signal[:, 1], rtol=0.01)
    unbalanced = ColourSensor(full_well=1e7, read_noise=0.0, blur_sigma=0.0, white_balance=(1.0, 1.0, 1.0))
    raw = unbalanced.capture(view.rgb(), view.inside, np.random.default_rng(0))[ground]
    assert np.median(raw[:, 2] / raw[:, 0]) > 1.05  # without it the skylit grey is bluish: the balance matters


def test_the_colour_camera_sees_the_same_green_as_the_uv_green_camera(garden, colour_view):
    view, camera = colour_view
    frame = build('teach', garden, ScenarioParameters(route_length=1.0, speed=1.0, cloud_cover=0.3), 1)[0]
    pair = Renderer(garden, camera, UV_GREEN).render(frame.pose, Sky(frame.hours, 0.3, cloud_seed=1))
    assert np.array_equal(pair.green, view.green) and np.array_equal(pair.sky, view.sky)
    assert set(view.radiance) == set(RGB) and set(pair.radiance) == set(UV_GREEN)


def test_the_signal_is_the_exposed_radiance_within_photon_and_read_noise(colour_view):
    view, _ = colour_view
    sensor = ColourSensor(blur_sigma=0.0)
    signal = sensor.capture(view.rgb(), view.inside, np.random.default_rng(3))
    gains = np.array(sensor.white_balance)
    electrons = view.rgb() * sensor.exposure(view.rgb(), view.inside)
    unsaturated = (electrons < 0.9 * sensor.full_well).all(axis=-1) & view.inside
    expected = electrons[unsaturated] * gains / sensor.full_well
    sigma = np.sqrt(electrons[unsaturated] + sensor.read_noise**2) * gains / sensor.full_well
    residual = (signal[unsaturated] - expected) / sigma
    assert abs(residual.mean()) < 0.05 and 0.9 < residual.std() < 1.1
    # automatic exposure: the 99th percentile of the brightest channel at 70 % of full scale
    assert np.percentile(signal[view.inside].max(axis=-1), 99) == pytest.approx(0.7, abs=0.03)
    assert np.array_equal(signal, sensor.capture(view.rgb(), view.inside, np.random.default_rng(3)))


def _image(pixels, encoding):
    """Return a rosbags sensor_msgs/Image of pixels, as a recording holds it."""
    T = typestore().types
    header = T['std_msgs/msg/Header'](T['builtin_interfaces/msg/Time'](0, 0), CAMERA_FRAME)
    return recording.image_message(T, header, pixels, encoding)


def _within_quantisation(decoded: np.ndarray, signal: np.ndarray, bits: int) -> np.ndarray:
    """Return per sample whether a decoded uint16 linear value is the signal up to its encoding's rounding."""
    if bits == 16:
        return np.abs(decoded / LINEAR_FULL_SCALE - signal) <= 0.5 / LINEAR_FULL_SCALE + 1e-7
    # 8-bit sRGB: half a code value in the sRGB domain, plus the decoding table's own rounding
    codes = (linear_to_srgb(decoded / LINEAR_FULL_SCALE) - linear_to_srgb(signal)) * 255
    return np.abs(codes) <= 0.5 + 0.02


@pytest.mark.parametrize('encoding', COLOUR_ENCODINGS)
def test_every_encoding_decodes_to_the_signal_within_quantisation(colour_view, encoding):
    view, _ = colour_view
    signal = ColourSensor().capture(view.rgb(), view.inside, np.random.default_rng(4))
    pixels = encode(signal, encoding)
    decoded = decode_image(_image(pixels, encoding))
    assert decoded.shape == signal.shape
    ok = _within_quantisation(decoded, signal, 16 if encoding.endswith('16') else 8)
    if encoding.startswith('bayer_'):
        # demosaicing keeps each photosite's own colour (borders aside) and interpolates the other two
        pattern = encoding.removeprefix('bayer_').rstrip('0123456789')
        native = np.zeros(signal.shape, bool)
        for k, colour in enumerate(pattern):
            row, column = divmod(k, 2)
            native[row::2, column::2, 'rgb'.index(colour)] = True
        native[[0, -1]] = native[:, [0, -1]] = False
        assert ok[native].all() and pixels.ndim == 2
    else:
        assert ok.all() and pixels.shape[2] == len(encoding.rstrip('0123456789').removeprefix('bayer_'))


@pytest.mark.parametrize(('codec', 'bits'), [('png', 8), ('png', 16), ('jpeg', 8)])
def test_compressed_frames_decode_to_the_signal(colour_view, codec, bits):
    view, _ = colour_view
    signal = ColourSensor().capture(view.rgb(), view.inside, np.random.default_rng(4))
    format_text, data = compressed(signal, codec, 95, bits)
    T = typestore().types
    header = T['std_msgs/msg/Header'](T['builtin_interfaces/msg/Time'](0, 0), CAMERA_FRAME)
    message = recording.compressed_message(T, header, format_text, data)
    decoded = decode_compressed(message)
    assert format_text == f'rgb{bits}; {codec} compressed bgr{bits}'
    if codec == 'png':  # lossless
        assert _within_quantisation(decoded, signal, bits).all()
    else:  # JPEG at quality 95 (chroma at half resolution): a few code values off on this small noisy frame with
        # its sharp rim, but unbiased in every channel (a swapped or mis-scaled channel is off by far more)
        codes = (linear_to_srgb(decoded / LINEAR_FULL_SCALE) - linear_to_srgb(signal)) * 255
        assert np.abs(codes).mean() < 3 and np.all(np.abs(codes.reshape(-1, 3).mean(axis=0)) < 0.75)
        srgb = linear_to_srgb(signal[view.inside]) * 255
        assert srgb[:, 2].mean() - srgb[:, 0].mean() > 5  # the frame is blue enough for a swap to show


def _colour_bag(tmp_path, name, *extra):
    out = tmp_path / name
    result = run_skynav('sim', 'bag', 'teach', '--world', 'mineral', '--seed', '2', *SMALL, *extra, '--out', str(out))
    assert result.returncode == 0, result.stderr
    return out


def test_a_compressed_colour_recording_has_the_contract_topics_and_says_what_camera(tmp_path):
    path = _colour_bag(tmp_path, 'colour.mcap', '--camera', 'colour-compressed', '--jpeg-quality', '80')
    with open_bag(path) as bag:
        assert {t: bag.topics[t].msgtype for t in bag.topics} == {
            COLOUR_COMPRESSED: 'sensor_msgs/msg/CompressedImage',
            COLOUR_CAMERA_INFO: 'sensor_msgs/msg/CameraInfo',
            GROUND_TRUTH_POSE: 'geometry_msgs/msg/PoseStamped',
            GROUND_TRUTH_MASK: 'sensor_msgs/msg/Image',
        }
        described = yaml.safe_load(bag.custom_data['skynav_sim'])
        messages: dict[str, list] = {}
        for message in bag.messages():
            messages.setdefault(message.topic, []).append(bag.deserialize(message))
    assert described['synthetic'] is True and described['camera'] == {
        'synthetic': True,
        'kind': 'colour-compressed',
        'encoding': 'rgb8',
        'white_balance': 'daylight (grey under the synthetic clear noon sky)',
        'srgb': '8-bit samples sRGB-encoded, 16-bit linear',
        'codec': 'jpeg',
        'jpeg_quality': 80,
    }
    stamps = {t: [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in ms] for t, ms in messages.items()}
    assert all(s == stamps[COLOUR_CAMERA_INFO] for s in stamps.values()) and len(stamps[COLOUR_CAMERA_INFO]) == 10
    frame, info = messages[COLOUR_COMPRESSED][0], messages[COLOUR_CAMERA_INFO][0]
    assert frame.format == 'rgb8; jpeg compressed bgr8' and frame.header.frame_id == CAMERA_FRAME
    assert decode_compressed(frame).shape == (info.height, info.width, 3) == (72, 96, 3)


def test_a_raw_colour_recording_carries_its_encoding(tmp_path):
    path = _colour_bag(tmp_path, 'bayer.mcap', '--camera', 'colour', '--encoding', 'bayer_gbrg16')
    with open_bag(path) as bag:
        assert set(bag.topics) == {
            COLOUR_IMAGE,
            COLOUR_CAMERA_INFO,
            GROUND_TRUTH_POSE,
            GROUND_TRUTH_MASK,
        }
        described = yaml.safe_load(bag.custom_data['skynav_sim'])['camera']
        frame = bag.deserialize(next(bag.messages([COLOUR_IMAGE])))
    assert (described['kind'], described['encoding']) == ('colour', 'bayer_gbrg16')
    assert (frame.encoding, frame.width, frame.height, frame.step) == ('bayer_gbrg16', 96, 72, 192)
    assert decode_image(frame).shape == (72, 96, 3)
    sheet = tmp_path / 'sheet.png'  # the preview shows a colour recording's frames
    result = run_skynav('sim', 'preview', '--bag', str(path), '--frames', '2', '--out', str(sheet))
    assert result.returncode == 0, result.stderr
    assert sheet.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and sheet.stat().st_size > 20_000


def test_same_seed_same_colour_bytes(tmp_path):
    # the file's own name is part of its rosbag2 metadata, so both copies get the same name
    copies = []
    for folder, seed in (('one', '2'), ('two', '2'), ('three', '3')):
        (tmp_path / folder).mkdir()
        out = tmp_path / folder / 'run.mcap'
        result = run_skynav(
            'sim', 'bag', 'teach', '--world', 'mineral', '--seed', seed, *SMALL, '--camera', 'colour-compressed',
            '--out', str(out),
        )  # fmt: skip
        assert result.returncode == 0, result.stderr
        copies.append(hashlib.sha256(out.read_bytes()).digest())
    assert copies[0] == copies[1] != copies[2]


@pytest.mark.parametrize(
    ('args', 'text'),
    [
        (['--camera', 'colour', '--encoding', 'mono8'], "not one of the colour camera's"),
        (['--encoding', 'rgb8'], "not one of the uv-green camera's"),
        (['--camera', 'colour-compressed', '--encoding', 'rgb16'], 'JPEG holds 8-bit samples only'),
        (['--camera', 'colour-compressed', '--jpeg-quality', '0'], 'not within 1-100'),
        (['--camera', 'colour', '--jpeg-quality', '50'], '--jpeg-quality is for'),
    ],
)
def test_an_impossible_camera_is_refused_before_anything_is_written(tmp_path, args, text):
    result = run_skynav('sim', 'bag', 'teach', *SMALL, *args, '--out', str(tmp_path / 'never.mcap'))
    assert result.returncode == 2 and text in result.stderr and 'Traceback' not in result.stderr, result.stderr
    assert list(tmp_path.iterdir()) == []


#: sha256 of small UV/green captures (mono8 and mono16 images, masks) computed with the code of e5a6ecd, before the
#: colour camera came: the UV/green camera's output must not change with it (the bundled recordings are fixtures).
UV_GREEN_DIGEST = 'f5da26c4e3efb90a46cb5dfaff7cb14c9708fa914b67d16db82879b309c19c7f'


def test_the_uv_green_camera_is_unchanged():
    digest = hashlib.sha256()
    camera = EquidistantCamera.for_field_of_view(64, 48, np.radians(200))
    for style, seed, time, clouds, encoding in (
        ('garden', 1, 'morning', 0.3, 'mono8'),
        ('mineral', 2, 'sunrise', 0.0, 'mono16'),
        ('park', 3, 'dawn', 0.6, 'mono8'),
    ):
        world = generate(style, seed)
        params = ScenarioParameters(
            hours=TIMES_OF_DAY[time], cloud_cover=clouds, route_length=1.0, speed=1.0, shake=3.0, offset=0.1
        )
        frames = build('repeat', world, params, seed)[:2]
        for capture in captures(world, camera, frames, encoding, seed):
            for array in (capture.uv, capture.green, capture.view.sky):
                digest.update(np.ascontiguousarray(array).tobytes())
    assert digest.hexdigest() == UV_GREEN_DIGEST


def test_camera_outputs_name_their_topics():
    assert set(CameraOutput().topics) == set(recording.TOPICS)
    assert set(CameraOutput('colour', 'bgr8').image_topics) == {COLOUR_IMAGE, COLOUR_CAMERA_INFO}
    assert CameraOutput('colour-compressed', 'rgb16', 'png').info_topic == COLOUR_CAMERA_INFO


def test_the_simulated_mower_feeds_its_colour_camera_to_the_graph(tmp_path):
    # one JPEG frame of the closed loop's camera through the skyline and SH nodes: a one-snapshot map
    from skynav_core.maps import MapStore
    from skynav_sim.closed_loop import snapshot_map

    world = generate('park', 3)
    camera = EquidistantCamera.for_field_of_view(96, 72, np.radians(200))
    place = np.array([0.5, 0.5])
    output = CameraOutput('colour-compressed', 'rgb8')
    snapshot_map(world, camera, place, 0.0, TIMES_OF_DAY['forenoon'], 3, tmp_path / 'colour.db', output=output)
    with MapStore.open(tmp_path / 'colour.db') as store:
        assert len(store) == 1 and np.isfinite(store.coefficients()).all()
