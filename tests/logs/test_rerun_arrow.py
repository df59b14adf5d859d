"""The Arrow arrays the loggers hand to Rerun are exactly what Rerun's own conversions make.

Rerun takes an array of a component's type as it is, without checking its contents: a wrong layout
would draw wrong lines, not fail. These tests compare with Rerun's conversions, so an upgrade of
the pinned Rerun that changes a type fails here.
"""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr

from rose_logs.rerun import arrow


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


@pytest.mark.parametrize("dims", [2, 3])
def test_strips_of_equal_length_match_rerun(rng, dims: int) -> None:
    lines = rng.normal(size=(4, 2, dims)) * 100.0  # float64, as the loggers compute them
    archetype = rr.LineStrips2D if dims == 2 else rr.LineStrips3D
    expected = archetype(lines.astype(np.float32)).strips.as_arrow_array()
    assert arrow.strips(lines).equals(expected)


@pytest.mark.parametrize("dims", [2, 3])
def test_ragged_strips_match_rerun(rng, dims: int) -> None:
    lines = [rng.normal(size=(n, dims)) for n in (181, 2, 2, 5)]
    archetype = rr.LineStrips2D if dims == 2 else rr.LineStrips3D
    expected = archetype([line.astype(np.float32) for line in lines]).strips.as_arrow_array()
    assert arrow.strips(lines).equals(expected)


def test_no_strips_match_rerun() -> None:
    expected = rr.LineStrips2D(np.empty((0, 2, 2), np.float32)).strips.as_arrow_array()
    assert arrow.strips(np.empty((0, 2, 2))).equals(expected)
    assert arrow.strips([]).equals(expected)
    expected_3d = rr.LineStrips3D(np.empty((0, 2, 3), np.float32)).strips.as_arrow_array()
    assert arrow.strips([], dims=3).equals(expected_3d)
    # Strips without points.
    for shape in ((3, 0, 2), (0, 0, 3)):
        archetype = rr.LineStrips2D if shape[-1] == 2 else rr.LineStrips3D
        lines = np.empty(shape, np.float32)
        assert arrow.strips(lines).equals(archetype(lines).strips.as_arrow_array())


def test_one_strip_as_an_array_matches_rerun(rng) -> None:
    line = rng.normal(size=(7, 2))
    expected = rr.LineStrips2D(line.astype(np.float32)).strips.as_arrow_array()
    assert arrow.strips(line).equals(expected)


@pytest.mark.parametrize("dims", [2, 3])
def test_points_match_rerun(rng, dims: int) -> None:
    positions = rng.normal(size=(6, dims))
    archetype = rr.Points2D if dims == 2 else rr.Points3D
    expected = archetype(positions.astype(np.float32)).positions.as_arrow_array()
    assert arrow.points(positions).equals(expected)
    assert arrow.points(positions[:0]).equals(archetype(positions[:0]).positions.as_arrow_array())
    assert arrow.points([], dims=dims).equals(archetype([]).positions.as_arrow_array())


def test_bad_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="shape"):
        arrow.points(np.zeros((3, 4)))
    with pytest.raises(ValueError, match="2D or 3D"):
        arrow.strips(np.zeros((2, 2, 4)))
    with pytest.raises(ValueError, match="all"):
        arrow.strips([np.zeros((2, 2)), np.zeros((2, 3))])


def test_images_match_rerun() -> None:
    image = np.arange(12, dtype=np.uint8).reshape(3, 4)
    expected = rr.SegmentationImage(image)
    assert arrow.image_buffer(image).equals(expected.buffer.as_arrow_array())
    assert arrow.u8_format(image).equals(expected.format.as_arrow_array())
    grey = rr.GridMap(
        data=image.reshape(-1),
        format=rr.components.ImageFormat(width=4, height=3, color_model="L", channel_datatype="U8"),
        cell_size=1.0,
    )
    assert arrow.u8_format(image, color_model="L").equals(grey.format.as_arrow_array())
    # One format per shape, shared: another shape gets its own.
    assert arrow.u8_format(image.T.copy()).equals(
        rr.SegmentationImage(image.T.copy()).format.as_arrow_array()
    )


def test_amplitude_curve_style_matches_rerun() -> None:
    from rose_logs.rerun import style
    from rose_logs.rerun.loggers import _curve_style

    expected = rr.LineStrips2D(
        [np.zeros((2, 2), np.float32)] * 4,
        colors=[style.CURVE_COLOR] + [style.PEAK_COLOR] * 3,
        radii=rr.Radius.ui_points([1.5, 1.0, 1.0, 1.0]),
    )
    colors, radii = _curve_style(3)
    assert colors.equals(expected.colors.as_arrow_array())
    assert radii.equals(expected.radii.as_arrow_array())


def _logged(components) -> list[tuple[str, object]]:
    """What ``rr.log`` sends of ``components`` (an archetype or a list of described batches)."""
    batches = (
        components.as_component_batches()
        if hasattr(components, "as_component_batches")
        else components
    )
    return [(str(b.component_descriptor()), b.as_arrow_array()) for b in batches]


@pytest.mark.parametrize(
    ("archetype", "fields"),
    [
        (rr.Points2D, {"positions": [(1.0, 2.0), (3.0, 4.5)], "labels": ["walls 12.5°", ""]}),
        (rr.Points3D, {"labels": []}),
        (rr.LineStrips2D, {"strips": [[(0.0, 1.0), (2.0, 3.0)]], "radii": 0.75}),
        (rr.Scalars, {"scalars": [0.25, float("nan"), 1.5]}),
        (rr.Scalars, {"scalars": 2.0}),
        (
            rr.GridMap,
            {
                "data": np.arange(6, dtype=np.uint8).tobytes(),
                "format": rr.components.ImageFormat(
                    width=3, height=2, color_model="L", channel_datatype="U8"
                ),
                "cell_size": 0.05,
                "translation": [1.0, -2.0, 0.5],
                "quaternion": rr.Quaternion(xyzw=[0.0, 0.0, 0.6, 0.8]),
            },
        ),
    ],
)
def test_described_components_are_the_archetypes(archetype, fields) -> None:
    """Logged without building the archetype, the components are the archetype's: its descriptors,
    its arrays (values converted by its own conversions, Arrow arrays taken as they are)."""
    expected = _logged(archetype.from_fields(**fields))
    ours = _logged(arrow.described(archetype, **fields))
    assert [name for name, _ in ours] == [name for name, _ in expected]
    # (str: an Arrow NaN is not equal to itself)
    assert all(
        a.type == b.type and str(a) == str(b) for (_, a), (_, b) in zip(ours, expected, strict=True)
    )
    # Arrow input of the component's type is passed through.
    as_arrow = {name.split(":")[-1]: array for name, array in expected}
    again = _logged(arrow.described(archetype, **as_arrow))
    assert all(a is b for (_, a), (_, b) in zip(again, expected, strict=True))
    assert arrow.texts(["a", "b°"]).equals(rr.components.TextBatch(["a", "b°"]).as_arrow_array())
    for value in ([0.25, float("nan"), -0.0], 2.0):
        expected_scalars = rr.components.ScalarBatch(value).as_arrow_array()
        assert arrow.floats(value).type == expected_scalars.type
        assert str(arrow.floats(value)) == str(expected_scalars)


def test_batches_are_the_archetypes_components() -> None:
    placement = rr.Transform3D(
        translation=[1.0, 2.0, 0.0],
        rotation=rr.RotationAxisAngle(axis=[0.0, 0.0, 1.0], radians=0.3),
        scale=[0.5, 0.5, 1.0],
    )
    ours, expected = _logged(arrow.batches(placement)), _logged(placement)
    assert [n for n, _ in ours] == [n for n, _ in expected]
    assert all(a.equals(b) for (_, a), (_, b) in zip(ours, expected, strict=True))
    clear, expected_clear = (
        _logged(arrow.batches(rr.Clear(recursive=True))),
        _logged(rr.Clear(recursive=True)),
    )
    assert [n for n, _ in clear] == [n for n, _ in expected_clear]
    assert all(a.equals(b) for (_, a), (_, b) in zip(clear, expected_clear, strict=True))


def test_image_placements_are_rerun_transforms(rng) -> None:
    """A map that grows moves its images with every snapshot: their placements are built as
    Arrow arrays (Rerun's Transform3D took about 0.1 ms each), the very components Rerun makes."""
    from rose_logs.rerun.loggers import _placement

    def placement_transform(
        translation: tuple[float, float], angle: float, scale: float
    ) -> rr.Transform3D:
        return rr.Transform3D(
            translation=[*translation, 0.0],
            rotation=rr.RotationAxisAngle(axis=[0.0, 0.0, 1.0], radians=angle),
            scale=[scale, scale, 1.0],
        )

    for translation, angle, scale in [((1.5, -2.25), 0.3, 0.05), ((0.0, 0.0), -0.0, 1.0)] + [
        ((float(x), float(y)), float(a), float(s))
        for x, y, a, s in rng.normal(size=(20, 4)) * [1e3, 1e5, 3.0, 1.0]
    ]:
        ours = _logged(_placement(translation, angle, scale))
        expected = _logged(placement_transform(translation, angle, scale))
        assert [n for n, _ in ours] == [n for n, _ in expected]
        assert all(a.equals(b) for (_, a), (_, b) in zip(ours, expected, strict=True))
        assert arrow.axis_angle((0.0, 0.0, 1.0), angle).equals(
            rr.components.RotationAxisAngleBatch(
                rr.RotationAxisAngle(axis=[0.0, 0.0, 1.0], radians=angle)
            ).as_arrow_array()
        )
