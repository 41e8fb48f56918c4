"""FastLSM deformable objects from Python: the node's scene, stepped without ROS.

    import deformable_flsm as flsm
    sim = flsm.Simulation.from_yaml("config/flsm.yaml", youngs_modulus=2e5)
    sim.step(30)
    x = sim.positions()          # (N, 3) view of the particles, no copy

The scene is the one flsm_node builds from the same parameters (the node's own loader and
scene builder); fit.py fits its material to a recording, batch.py runs many scenes.
"""
# The package spans this directory and the build's (the compiled _core, the messages): found
# whichever of them a process imports first (catkin's devel space, or a Dask worker spawned
# with this directory first on its path).
__path__ = __import__("pkgutil").extend_path(__path__, __name__)

__all__ = ["ParamError", "Simulation", "load_params"]


def __getattr__(name):
    # The compiled core is loaded on first use: a node that imports only the messages
    # (deformable_flsm.msg) does not load it.
    if name in __all__:
        from deformable_flsm import scene
        return getattr(scene, name)
    raise AttributeError("module 'deformable_flsm' has no attribute '%s'" % name)
