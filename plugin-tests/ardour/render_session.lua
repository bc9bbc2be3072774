-- Headless Ardour session for plugin-tests/ardour/test_ardour.py, run as
--   ardour7-lua render_session.lua
-- with everything it needs in the environment (test_ardour.py sets it):
--   MC_MODE      "create": a new session with a MIDI track holding the note
--                generator ("MC Test Notes", a Lua DSP script in the user's
--                scripts/ folder) and the Modal Contact VST3 after it; the
--                session is saved after the takes.
--                "load": the session saved by a "create" run, as it is.
--   MC_SESSION_DIR, MC_SESSION_NAME, MC_RATE (create only)
--   MC_OUT_DIR   where the takes are exported (<take>.wav)
--   MC_PRESET    id of the export preset (32-bit float WAV, no dither, no
--                normalisation) that test_ardour.py writes to the user's
--                export/ folder
--   MC_SAMPLES   length of each take, from sample 0
--   MC_TAKES     takes separated by "|": "name" or "name:Param=value,..."
--                (a parameter by its label; a value in the parameter's own
--                unit as Ardour shows it for this VST3: dB for Output gain,
--                the list position for Scene, 0 = Bell, 2 = Marimba bar; Ardour
--                7.3 lists no scale points for it). Parameter changes
--                accumulate from take to take.
-- Everything the driver reads is printed on lines starting with "MC ".

local function getenv (k)
	local v = os.getenv (k)
	assert (v and v ~= "", "environment variable " .. k .. " is not set")
	return v
end

local MODE = getenv ("MC_MODE")
local DIR = getenv ("MC_SESSION_DIR")
local NAME = getenv ("MC_SESSION_NAME")
local OUT = getenv ("MC_OUT_DIR")
local PRESET = getenv ("MC_PRESET")
local SAMPLES = math.tointeger (tonumber (getenv ("MC_SAMPLES")))
local TAKES = os.getenv ("MC_TAKES") or ""
local PLUGIN = "Modal Contact"
local GENERATOR = "MC Test Notes"
local TRACK = "synth"

local function say (...)
	local t = {}
	for _, v in ipairs ({...}) do
		if type (v) == "number" then
			t[#t + 1] = string.format ("%.9g", v)
		else
			t[#t + 1] = tostring (v)
		end
	end
	print ("MC " .. table.concat (t, "\t"))
end

local be = AudioEngine:set_backend ("None (Dummy)", "", "")
assert (be, "no dummy backend")
say ("backend", AudioEngine:current_backend_name ())

local track
if MODE == "create" then
	local rate = math.tointeger (tonumber (getenv ("MC_RATE")))
	assert (create_session (DIR, NAME, rate), "create_session failed")
	-- the plugin as Ardour's scan cache lists it
	local info = nil
	for p in ARDOUR.LuaAPI.list_plugins ():iter () do
		if p.name == PLUGIN and p.type == ARDOUR.PluginType.VST3 then
			info = p
			say ("plugin_info", p.unique_id, p.path)
		end
	end
	assert (info, "Modal Contact VST3 is not in Ardour's plugin list")
	-- a MIDI track (1 MIDI in, 2 audio out) with the plugin as its instrument
	local tl = Session:new_midi_track (
		ARDOUR.ChanCount (ARDOUR.DataType ("midi"), 1),
		ARDOUR.ChanCount (ARDOUR.DataType ("audio"), 2),
		false, info, nil, nil, 1, TRACK,
		ARDOUR.PresentationInfo.max_order, ARDOUR.TrackMode.Normal, true, false)
	assert (tl:size () == 1, "new_midi_track failed")
	track = tl:front ()
	-- the note generator, inserted before the instrument
	local gen = ARDOUR.LuaAPI.new_luaproc (Session, GENERATOR)
	assert (not gen:isnil (), "no Lua DSP script named " .. GENERATOR)
	assert (track:add_processor_by_index (gen, 0, nil, true) == 0, "adding the generator failed")
elseif MODE == "load" then
	assert (load_session (DIR, NAME), "load_session failed")
	local r = Session:route_by_name (TRACK)
	assert (not r:isnil (), "no track " .. TRACK .. " in the loaded session")
	track = r:to_track ()
else
	error ("MC_MODE must be create or load")
end
say ("rate", Session:nominal_sample_rate (), "buffer", be:buffer_size ())

-- the processor chain, in order; find the instrument
local insert = nil
for i = 0, 64 do
	local p = track:nth_processor (i)
	if p:isnil () then break end
	say ("proc", i, p:name ())
	if p:name () == PLUGIN then
		insert = p
	end
end
assert (insert, "the track has no " .. PLUGIN .. " processor")
local plugin = insert:to_insert ():plugin (0)
assert (plugin:get_info ().type == ARDOUR.PluginType.VST3, "the instrument is not the VST3")

-- the plugin's parameters by label: index for set_processor_param, port id
local params = {}
for j = 0, plugin:parameter_count () - 1 do
	local ok = false
	local pid = plugin:nth_parameter (j, ok)
	if plugin:parameter_is_input (pid) and plugin:parameter_label (pid) ~= "hidden" then
		params[plugin:parameter_label (pid)] = { index = j, port = pid }
	end
end

local function param_value (label)
	local p = assert (params[label], "no parameter " .. label)
	local ok = false
	local v = ARDOUR.LuaAPI.get_processor_param (insert, p.index, ok)
	return v
end

local function report_params (tag)
	for label, p in pairs (params) do
		say ("param", tag, label, param_value (label))
	end
end

local function set_param (label, text)
	local p = assert (params[label], "no parameter " .. label)
	local v = assert (tonumber (text), label .. ": not a number: " .. text)
	assert (ARDOUR.LuaAPI.set_processor_param (insert, p.index, v),
		"set_processor_param " .. label .. " = " .. text .. " refused")
	return v
end

-- gain and routing between the plugin and the export (master bus)
local master = Session:master_out ()
-- Ardour connects a new track's outputs to the master bus from its
-- auto-connect thread, a moment after the track is made: wait for it
local function routed ()
	local o, i = track:output (), master:input ()
	return o:nth (0):connected_to (i:nth (0):name ()) and o:nth (1):connected_to (i:nth (1):name ())
		and not o:nth (0):connected_to (i:nth (1):name ()) and not o:nth (1):connected_to (i:nth (0):name ())
end
for _ = 1, 50 do
	if routed () then break end
	sleep (0.1)
end
say ("routed", routed () and 1 or 0)
assert (routed (), "the track's outputs are not connected 1:1 to the master bus")
say ("fader", track:gain_control ():get_value ())
say ("trim", track:trim_control ():get_value ())
say ("pan_azimuth", track:pan_azimuth_control ():get_value ())
say ("panner_bypassed", track:panner_shell ():bypassed () and 1 or 0)
say ("master_fader", master:gain_control ():get_value ())
say ("master_trim", master:trim_control ():get_value ())
say ("track_outputs", track:n_outputs ():n_audio ())
say ("master_io", master:n_inputs ():n_audio (), master:n_outputs ():n_audio ())
say ("latency", "plugin", insert:signal_latency (), "track", track:signal_latency (),
	"playback", track:playback_latency (false), "worst_output", Session:worst_output_latency (),
	"worst_route", Session:worst_route_latency (), "preroll", Session:worst_latency_preroll ())
report_params ("initial")

for take in TAKES:gmatch ("[^|]+") do
	local name, assignments = take:match ("^([^:]+):?(.*)$")
	for a in assignments:gmatch ("[^,]+") do
		local label, text = a:match ("^(.-)=(.*)$")
		local v = set_param (label, text)
		say ("set", name, label, v, param_value (label))
	end
	-- let the engine run: the plugin picks the change up at its next block
	-- and compiles a new scene on its worker; earlier notes have long died
	sleep (1.0)
	local e = Session:simple_export ()
	assert (e:set_preset (PRESET), "no export preset " .. PRESET)
	e:set_name (name)
	e:set_folder (OUT)
	e:set_range (0, SAMPLES)
	local ok = e:run_export ()
	say ("export", name, ok and "ok" or "failed")
end

if MODE == "create" then
	local rv = Session:save_state ("", false, false, false, false, false)
	say ("saved", rv)
end
say ("done")
close_session ()
say ("closed")
