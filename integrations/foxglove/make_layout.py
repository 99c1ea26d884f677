#!/usr/bin/env python3
"""Writes hexcue-layout.json: a Foxglove layout for hexcue recordings and live sessions.

The panel configurations are built with the types of Foxglove's Python SDK
(`pip install foxglove-sdk`, module `foxglove.layouts`), so that their keys are Foxglove's own;
they are wrapped in the layout file format that Foxglove's "Import from file…" reads
(`configById` + the `layout` split tree). See docs/foxglove.md.

    python3 integrations/foxglove/make_layout.py > integrations/foxglove/hexcue-layout.json
"""

import json

import foxglove.layouts as fl

ALGORITHMS = ["smpc", "mpc", "cwf"]
# Okabe-Ito, as hexcue's own figures (src/plot/mod.rs): the reference is black.
COLOURS = {"reference": "#000000", "smpc": "#0072b2", "mpc": "#d55e00", "cwf": "#009e73"}
CHANNELS = [
    ("fx", "specific_force[0]", "perceived fx (m/s²)"),
    ("fy", "specific_force[1]", "perceived fy (m/s²)"),
    ("fz", "specific_force[2]", "perceived fz (m/s²)"),
    ("wx", "angular_velocity[0]", "perceived ωx (rad/s)"),
    ("wy", "angular_velocity[1]", "perceived ωy (rad/s)"),
    ("wz", "angular_velocity[2]", "perceived ωz (rad/s)"),
]


def config(panel) -> dict:
    """A panel's configuration as the SDK writes it, with its title where the app keeps it."""
    d = json.loads(fl.Layout(content=panel).to_json())["content"]
    cfg = d.get("config", {})
    if d.get("title"):
        cfg["foxglovePanelTitle"] = d["title"]
    return cfg


def plot(channel: str, field: str, title: str):
    series = [
        fl.PlotSeries(
            value=f"/aircraft/perceived.{field}",
            label="reference",
            color=COLOURS["reference"],
            enabled=True,
            timestamp_method="receiveTime",
        )
    ] + [
        fl.PlotSeries(
            value=f"/{alg}/perceived.{field}",
            label=alg,
            color=COLOURS[alg],
            enabled=True,
            timestamp_method="receiveTime",
        )
        for alg in ALGORITHMS
    ]
    return fl.PlotPanel(
        title=title,
        config=fl.PlotConfig(
            paths=series,
            show_legend=True,
            legend_display="floating",
            show_x_axis_labels=True,
            show_y_axis_labels=True,
            is_synced=True,
            x_axis_val="timestamp",
        ),
    )


def main() -> None:
    three_d = fl.ThreeDeePanel(
        title="platforms (smpc, mpc, cwf from left to right)",
        config=fl.ThreeDeeConfig(
            follow_tf="world",
            follow_mode="follow-none",
            camera_state=fl.ThreeDeeCameraState(
                distance=22.0,
                perspective=True,
                phi=62.0,
                theta_offset=-35.0,
                target=(0.0, 0.0, 3.0),
                target_offset=(0.0, 0.0, 0.0),
                target_orientation=(0.0, 0.0, 0.0, 1.0),
                fovy=45.0,
                near=0.5,
                far=5000.0,
            ),
            topics={
                # Every algorithm's rig is on the one /scene topic (docs/foxglove.md).
                "/scene": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
            },
        ),
    )
    modes = fl.StateTransitionsPanel(
        title="S-MPC controller",
        config=fl.StateTransitionsConfig(
            paths=[
                fl.StateTransitionsSeries(
                    value="/smpc/controller.mode", label="smpc mode", timestamp_method="receiveTime"
                )
            ],
            is_synced=True,
        ),
    )
    events = fl.LogPanel(title="events", config=fl.LogConfig(topic_to_render="/events"))

    panels = {"3D!hexcue": config(three_d)}
    for key, field, title in CHANNELS:
        panels[f"Plot!{key}"] = config(plot(key, field, title))
    panels["StateTransitions!smpc"] = config(modes)
    panels["RosOut!events"] = config(events)

    def split(direction, first, second, percent=50):
        return {
            "direction": direction,
            "first": first,
            "second": second,
            "splitPercentage": percent,
        }

    forces = split("column", "Plot!fx", split("column", "Plot!fy", "Plot!fz"), 33.3)
    rates = split("column", "Plot!wx", split("column", "Plot!wy", "Plot!wz"), 33.3)
    left = split("column", "3D!hexcue", split("row", "StateTransitions!smpc", "RosOut!events"), 70)
    layout = {
        "configById": panels,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1},
        "layout": split("row", left, split("row", forces, rates), 50),
    }
    print(json.dumps(layout, indent=2, ensure_ascii=False))


if __name__ == "__main__":
    main()
