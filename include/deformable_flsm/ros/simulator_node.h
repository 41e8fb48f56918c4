/// @file simulator_node.h
/// The ROS face of the simulation: parameters in, commands in, state out. All physics is in the
/// core (through SimulationLoop); this class owns the ROS handles and converts at the edges.
#pragma once

#include "deformable_flsm/ros/log_queue.h"
#include "deformable_flsm/ros/camera_topics.h"
#include "deformable_flsm/ros/collider_topics.h"
#include "deformable_flsm/ros/tactile_topics.h"
#include "deformable_flsm/ros/command_validator.h"
#include "deformable_flsm/runtime/commands.h"
#include "deformable_flsm/ros/interactive_drag.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/runtime/problem_reporter.h"
#include "deformable_flsm/ros/reconfigure.h"
#include "deformable_flsm/runtime/scene.h"
#include "deformable_flsm/runtime/sequence_gaps.h"
#include "deformable_flsm/runtime/simulation_loop.h"
#include "deformable_flsm/ros/state_publisher.h"

#include <deformable_flsm/AddObject.h>
#include <deformable_flsm/DragCommand.h>
#include <deformable_flsm/FlsmConfig.h>
#include <deformable_flsm/ForceCommand.h>
#include <deformable_flsm/PinBox.h>
#include <deformable_flsm/RemoveObject.h>
#include <deformable_flsm/Step.h>
#include <geometry_msgs/TransformStamped.h>
#include <rosgraph_msgs/Clock.h>
#include <ros/callback_queue.h>
#include <ros/node_handle.h>
#include <ros/service_server.h>
#include <ros/spinner.h>
#include <ros/subscriber.h>
#include <ros/timer.h>
#include <ros/wall_timer.h>
#include <std_srvs/Empty.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <Eigen/Geometry>

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {

/// flsm_node's topics, services and timers (see README for the full table):
///   in   ~drag (DragCommand), ~force (ForceCommand), ~collider (ColliderCommand), RViz mouse
///        via ~drag_marker; with ~objects also ~objects/<name>/drag and ~objects/<name>/force
///        (the top-level topics address the first object)
///   out  ~mesh, ~surface, ~particles, ~lattice, ~colliders (only while subscribed), ~state,
///        ~contact_wrenches, tf
///   srv  ~reset, ~release_all, ~pin_box (with ~objects also ~objects/<name>/pin_box,
///        ~add_object and ~remove_object), ~pause, ~unpause, ~step; dynamic_reconfigure on ~
///   time ~clock sim: /clock out, with each step's tf (onTick, on the simulation thread);
///        ~clock follow: /clock in (onClock, on the state thread)
///
/// Threads: the simulation thread (SimulationLoop) steps the solver; the main thread (ros::spin)
/// runs the publish timer of tf, ~contact_wrenches, the meshes, clouds and markers (one snapshot,
/// one stamp) and the RViz feedback; the state thread, with its own queue and timer, sends
/// ~state at the same rate and samples the frames colliders follow, so that on a starved machine
/// a slow mesh (5 MB for the bunny) never holds up the state nor the followed colliders; a
/// further spinner thread with its own queue
/// serves ~drag, ~force and ~collider, a third the services, so that a service waiting for the
/// simulation never delays publishing nor another client's commands, and a fourth
/// dynamic_reconfigure, whose every change writes each parameter to the master, one call each:
/// on the main thread a slow master would hold up the publish timer behind them. Commands
/// never wait for tf: a frame tf does not know now is refused at once (see lookupTransform), so
/// that a client commanding in a frame nobody publishes cannot starve the others.
///
/// The node owns and wires the parts: StatePublisher (what goes out each tick), InteractiveDrag
/// (the RViz mouse), Reconfigure (dynamic_reconfigure), ProblemReporter (the log); the commands'
/// subscribers and services, their validation and their way into the simulation thread are here.
class SimulatorNode {
 public:
  /// @param[in] nh      public handle
  /// @param[in] pnh     private handle ("~"): topics, services and parameters live here
  /// @param[in] params      validated node parameters
  /// @param[in] scene       the built objects; their World moves into the simulation thread
  /// @param[in] namespaced  the objects came from ~objects: each has its topics under
  ///                        ~objects/<name>/ (false: the single object's topics under ~)
  SimulatorNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, const NodeParams& params,
                WorldScene scene, bool namespaced);
  ~SimulatorNode();

 private:
  // Start-up, in this order (the constructor).
  /// The tactile sensors' recordings, the simulation loop (not started) and /clock.
  void startLoop(WorldScene& scene);
  /// Each object's command validator.
  void makeValidators();
  /// The state publisher, the scene's summed pins and the problem reporter.
  void makeReporter();
  /// Topics, colliders, dynamic_reconfigure and the interactive drag handles.
  void makeInterfaces();
  /// The loop's source of attached frames, the tactile and camera topics (before the loop
  /// starts: a sensor that cannot start leaves no thread running).
  void makeSensors();
  /// The simulation loop, the timers and the spinners.
  void startThreads();
  void advertise();
  void onPublishTimer(const ros::TimerEvent& event);
  /// The newest snapshot out: tf, wrenches, markers, meshes and clouds (the main thread).
  void publishNewest();
  void onStateTimer(const ros::TimerEvent& event);
  /// ~state of the newest snapshot (the state thread).
  void publishState();

  // Time (NodeParams::clock).
  /// @throws ParamError when ~clock and /use_sim_time disagree (the node's timers would never
  /// fire, or run on a clock nobody serves).
  void checkClock() const;
  /// The stamp of state `s`: its time in the node's clock (wall: when it was computed; sim and
  /// follow: its simulated time); at rest (and paused, with ~clock wall), the time now, as the
  /// state holds on.
  ros::Time stampOf(const Snapshot& s) const;
  /// ~clock follow: `stamp` lies beyond the followed clock (which went back, and the loop has
  /// not reset yet): such a state is not sent.
  bool aheadOfTheClock(const ros::Time& stamp) const;
  /// Whether state `s` may be sent, its stamp (stampOf()) in `stamp`: not before the loop
  /// followed a first time (the state has no time on that clock yet; a busy machine can run a
  /// publish timer first), nor ahead of the followed clock.
  bool sendable(const Snapshot& s, ros::Time& stamp) const;
  /// ~clock sim, on the simulation thread: each tick's tf (the objects' and colliders' frames of
  /// the new state, or the last state's again at rest), then /clock.
  void onTick(double time, const Snapshot* state);
  /// ~clock follow: the time the simulation follows.
  void onClock(const rosgraph_msgs::Clock::ConstPtr& clock);
  bool onPause(std_srvs::Empty::Request& req, std_srvs::Empty::Response& res);
  bool onUnpause(std_srvs::Empty::Request& req, std_srvs::Empty::Response& res);
  bool onStep(Step::Request& req, Step::Response& res);

  // Commands in.
  /// (the event names the publisher: messages missing from its numbering are counted, see
  /// SequenceGaps)
  /// Subscribes ~<prefix>drag, ~<prefix>force and advertises ~<prefix>pin_box for object
  /// `object` (index in objects_).
  void subscribeCommands(std::size_t object, const std::string& prefix, ros::Subscriber& dragSub,
                         ros::Subscriber& forceSub, ros::ServiceServer& pinBoxSrv);
  /// (`object`: the index of the object the topic addresses; `topic`: its name, for
  /// SequenceGaps)
  void onDrag(std::size_t object, const std::string& topic,
              const ros::MessageEvent<const DragCommand>& event);
  void onForce(std::size_t object, const std::string& topic,
               const ros::MessageEvent<const ForceCommand>& event);
  /// The RViz mouse's drags: validated and sent like ~drag; true when accepted.
  bool onMouseDrag(std::size_t object, const DragCommand& drag);
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onReleaseAll(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onPinBox(std::size_t object, PinBox::Request& req, PinBox::Response& res);
  /// ~add_object: parses the entry, builds the object here on the service thread (the mesh
  /// load and voxelization never hold up a step), hands it to the simulation thread and, once
  /// it is in, advertises its topics and subscribes its commands.
  bool onAddObject(AddObject::Request& req, AddObject::Response& res);
  bool onRemoveObject(RemoveObject::Request& req, RemoveObject::Response& res);
  /// A refusal of ~add_object or ~remove_object: counted under `reason`, the answer says why.
  template <class Response>
  bool refuseObject(const std::string& reason, const std::string& why, Response& res);
  /// false (counted as invalid_params) when the change is refused: nothing changes.
  bool onReconfigure(const FlsmConfig& config);
  /// Sends a command to the simulation thread, to object `object` ("" = the first, or the
  /// whole scene for colliders, reset and release-all); waits for its outcome when `wait`.
  CommandOutcome send(CommandBody body, bool wait, const std::string& object = std::string());
  /// Submits and waits for the simulation thread's answer however long it takes (while ROS runs):
  /// an object's addition or removal must reach the node's lists exactly when it reaches the
  /// World's, or its topics and the simulation would disagree for good.
  CommandOutcome sendAndWaitForTheAnswer(CommandBody body);
  void rejected(const Rejection& why);
  /// The transform at `stamp` if tf has it, else the latest one, else false: it never waits,
  /// except once, when the first command in a foreign frame starts the tf listener (see
  /// kFirstTransformTimeout).
  bool lookupTransform(const std::string& frame, const ros::Time& stamp, Eigen::Isometry3d& T,
                       std::string& why);
  /// Starts the tf listener if it is not running; true when this call started it.
  bool startTfListener();
  /// Where a frame that drags are attached to (DragCommand ATTACH) is now: the simulation loop's
  /// FrameSource, called from the simulation thread before every step. tf's latest transform,
  /// never waiting; false, with a throttled warning, while the frame is unknown or stale.
  bool attachedFrame(const std::string& frame, Eigen::Isometry3d& simFromFrame);

  /// Log lines of every thread but the main one, written by a thread of its own (declared
  /// first: destroyed after every thread that posts to it).
  std::unique_ptr<LogQueue> log_;
  InstalledLogQueue logInstalled_;
  ros::NodeHandle nh_, pnh_;
  ros::NodeHandle stateNh_;  ///< private namespace, served by stateSpinner_ (the state thread)
  ros::CallbackQueue stateQueue_;
  Snapshot summary_;  ///< the state thread's copy of the newest snapshot's summary
  ros::NodeHandle commandNh_;  ///< private namespace, served by commandSpinner_
  ros::CallbackQueue commandQueue_;
  ros::NodeHandle serviceNh_;  ///< private namespace, served by serviceSpinner_
  ros::CallbackQueue serviceQueue_;
  /// private namespace, served by reconfigureSpinner_: dynamic_reconfigure writes every
  /// parameter of a change to the master, one call each, and a slow master must not hold up
  /// the publish timer on the main thread
  ros::NodeHandle reconfigureNh_;
  ros::CallbackQueue reconfigureQueue_;
  std::mutex paramsMutex_;  ///< params_ between onReconfigure and the publish timer's reporter_
  NodeParams params_;
  /// the objects (lattice, render mesh, embedding, start-up figures), in the order they were
  /// added (the World's order); one removed at run time stays (its ObjectCommands say removed),
  /// so that indices and the references StatePublisher keeps stay valid
  std::deque<SceneObject> objects_;
  /// objects_ and commands_ grow, and objects go, on the service thread (exclusive) while the
  /// publish timer, the state timer and the command callbacks read them (shared: none of them
  /// waits for another, the state never for a mesh)
  std::shared_mutex objectsMutex_;
  /// what ProblemReporter warns about: the first object's, with the pins of every object
  SceneInfo sceneInfo_;
  bool namespaced_ = false;
  std::shared_ptr<CommandStats> stats_;
  SequenceGaps gaps_;  ///< of ~drag and ~force, on the command spinner's thread
  std::unique_ptr<SimulationLoop> loop_;
  /// One object's command topics: its validator (its size and place), and with ~objects its
  /// subscribers and service under ~objects/<name>/.
  struct ObjectCommands {
    std::unique_ptr<CommandValidator> validator;
    ros::Subscriber dragSub, forceSub;
    ros::ServiceServer pinBoxSrv;
    bool removed = false;  ///< taken out with ~remove_object: its handles are shut down
  };
  std::deque<ObjectCommands> commands_;
  /// objects (indices into objects_) whose RViz handles the main thread is still to add or
  /// erase: ~add_object and ~remove_object run on the service thread, the mouse on the main one
  std::mutex handlesMutex_;
  std::vector<std::pair<std::size_t, visualization_msgs::InteractiveMarker>> handlesToAdd_;
  std::vector<std::size_t> handlesToRemove_;
  std::unique_ptr<ColliderTopics> colliders_;  ///< ~collider, ~contact_wrenches, ~colliders
  std::unique_ptr<CameraTopics> cameras_;      ///< ~cameras, on a thread of their own
  std::unique_ptr<TactileTopics> tactile_;     ///< ~tactile, with each publish tick

  tf2_ros::Buffer tfBuffer_;
  std::mutex tfListenerMutex_;
  std::unique_ptr<tf2_ros::TransformListener> tfListener_;  ///< started by the first lookup

  std::unique_ptr<StatePublisher> publisher_;
  std::unique_ptr<ProblemReporter> reporter_;
  ros::Subscriber dragSub_, forceSub_;
  ros::ServiceServer resetSrv_, releaseAllSrv_, pinBoxSrv_, addObjectSrv_, removeObjectSrv_;
  ros::ServiceServer pauseSrv_, unpauseSrv_, stepSrv_;
  /// ~clock sim: /clock, and the tf of each tick (the simulation thread's)
  ros::Publisher clockPub_;
  tf2_ros::TransformBroadcaster tickBroadcaster_;
  std::vector<geometry_msgs::TransformStamped> tickTransforms_;
  /// ~clock follow: /clock in
  ros::Subscriber clockSub_;
  /// the newest stamp tf was sent with from the publish timer: none is sent twice
  ros::Time lastTfStamp_;
  /// the sequence of the newest snapshot published (publishNewest()), for ~step to wait on
  std::atomic<std::uint64_t> published_{0};
  /// ~step: the one-shot timer that publishes the state the steps reached
  ros::WallTimer stepPublish_;
  /// ~pause: the one-shot timer that sends ~state with paused set
  ros::WallTimer pauseState_;
  ros::Timer publishTimer_, stateTimer_;
  std::unique_ptr<ros::AsyncSpinner> stateSpinner_, commandSpinner_, serviceSpinner_, reconfigureSpinner_;
  std::unique_ptr<Reconfigure> reconfigure_;
  std::unique_ptr<InteractiveDrag> mouse_;
};

}  // namespace deformable_flsm
