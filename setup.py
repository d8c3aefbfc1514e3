"""ament_python package ``amb_wavelet_control``: the four parts and their tools."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "amb_wavelet_control"

# Node executables (``ros2 run amb_wavelet_control <name>``) and command-line tools.
NODES = {
    "fault_monitor": "amb_fault_monitor.node:main",
    "plant_sim": "amb_plant_sim.node:main",
    "recorder": "amb_tools.recorder_node:main",
    "replay_bridge": "amb_tools.replay_bridge:main",
    "wavelet_controller": "amb_controller.node:main",
    "wavelet_filterbank": "amb_wavelet.node:main",
    "wavelet_stack": "amb_apps.stack:main",
}
TOOLS = {
    "amb-acceptability": "amb_apps.acceptability:main",
    "amb-bound": "amb_apps.bound_cli:main",
    "amb-compare": "amb_apps.compare_cli:main",
    "amb-early-model": "amb_apps.early_model_cli:main",
    "amb-fault-eval": "amb_apps.eval_cli:main",
    "amb-modal": "amb_plant_sim.modal_cli:main",
    "amb-prediction": "amb_apps.prediction_cli:main",
    "amb-report": "amb_apps.report_cli:main",
    "amb-run": "amb_apps.run_cli:main",
    "amb-sim": "amb_apps.sim_cli:main",
    "amb-wavelet-info": "amb_wavelet.info_cli:main",
}

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=["amb_*"], exclude=["amb_msgs", "amb_msgs.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml")),
        (f"share/{PACKAGE}/config/scenarios", glob("config/scenarios/*.yaml")),
        (f"share/{PACKAGE}/config/scenarios/faults", glob("config/scenarios/faults/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="amb_wavelet_control maintainers",
    maintainer_email="amb-wavelet-control@example.com",
    description="Wavelet fault detection and transient control of flexible rotors on AMBs",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [f"{name} = {target}" for name, target in {**NODES, **TOOLS}.items()],
    },
)
